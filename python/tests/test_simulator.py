"""retrace.Simulator against `retrace sim render`: the same scenario and options give the same frames and poses."""

import numpy as np
import pytest
import retrace

from conftest import FRAMES, REPEAT_OFFSET, cli_error


def read_poses(path):
    return np.loadtxt(path).reshape(-1, 3, 4)


def test_simulator_renders_the_drive_sim_render_writes(drives):
    simulator = retrace.Simulator(frames=FRAMES, width=320, height=240, seed=3, variant="repeat",
                                  lateral_offset=REPEAT_OFFSET)
    assert simulator.expected_frames == FRAMES
    rendered = list(simulator)
    written = list(retrace.Sequence(drives.repeat))
    poses = read_poses(drives.repeat / "poses.txt")
    times = np.loadtxt(drives.repeat / "times.txt")
    assert len(rendered) == len(written) == len(poses) == FRAMES
    for frame, expected, pose, time in zip(rendered, written, poses, times):
        assert frame.image.dtype == np.uint8 and frame.image.shape == (240, 320)
        np.testing.assert_array_equal(frame.image, expected.image)  # PNG is lossless
        np.testing.assert_allclose(frame.world_from_cam[:3], pose, atol=1e-6)  # poses.txt has 9 digits or so
        np.testing.assert_array_equal(frame.world_from_cam[3], [0, 0, 0, 1])
        assert frame.timestamp == pytest.approx(time, abs=1e-6)
    # The car drives on along the route.
    first, last = rendered[0].world_from_cam, rendered[-1].world_from_cam
    assert rendered[-1].progress > 20.0
    assert np.linalg.norm(last[:3, 3] - first[:3, 3]) > 20.0
    assert simulator.next_frame() is None


def test_simulator_records_like_sim_render(drives, tmp_path):
    summary = retrace.Simulator(frames=5, width=320, height=240, seed=3).record(tmp_path / "drive")
    assert summary["frames"] == 5 and not summary["stopped_at_route_end"]
    for name in ("times.txt", "poses.txt", "calib.txt", "camera.yaml", "scenario.yaml"):
        assert (tmp_path / "drive" / name).exists(), name
    ours = list(retrace.Sequence(tmp_path / "drive"))
    theirs = [f for _, f in zip(range(5), retrace.Sequence(drives.teach))]
    for a, b in zip(ours, theirs):
        np.testing.assert_array_equal(a.image, b.image)
    np.testing.assert_array_equal(read_poses(tmp_path / "drive" / "poses.txt"),
                                  read_poses(drives.teach / "poses.txt")[:5])


def test_simulator_renders_any_pose():
    simulator = retrace.Simulator(frames=2, width=160, height=120)
    first = simulator.next_frame()
    again = simulator.render_at(first.world_from_cam, time=first.timestamp)
    assert again.shape == (120, 160)
    # The same view up to the sensor noise of another seed.
    assert np.abs(again.astype(int) - first.image.astype(int)).mean() < 8.0


def test_simulator_refuses_what_sim_render_refuses(tmp_path):
    for options, cli in (({"frames": -1}, ["--frames", "-1"]),
                         ({"pedestrians": 100000000}, ["--pedestrians", "100000000"]),
                         ({"lighting": "disco"}, ["--lighting", "disco"])):
        with pytest.raises(retrace.InputError) as error:
            retrace.Simulator(**options)
        assert str(error.value) == cli_error("sim", "render", "--out", tmp_path / "x", *cli)
    scenario = tmp_path / "town.yaml"
    scenario.write_text("town:\n  pedestrians: wide\n")
    with pytest.raises(retrace.InputError) as error:
        retrace.Simulator(scenario)
    assert str(error.value) == cli_error("sim", "render", "--scenario", scenario, "--out", tmp_path / "x")
    assert str(scenario) in str(error.value)
    with pytest.raises(ValueError, match="variant"):
        retrace.Simulator(variant="night")
    assert "town:" in retrace.example_scenario()
