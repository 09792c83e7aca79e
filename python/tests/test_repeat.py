"""retrace.Localizer against `retrace repeat` on the same frames: the same state, arc and steering per frame."""

import threading
import time

import numpy as np
import pytest
import retrace

from conftest import REPEAT_OFFSET, cli_error, read_csv


def assert_same_as_run_csv(result, row):
    """One frame of the Localizer against its row of run.csv (the command line's formatting of the same values)."""
    assert result.frame_index == int(row["frame"])
    assert result.state == row["state"]
    assert (result.arc, result.node_from, result.node_to) == (int(row["arc"]), int(row["node_from"]),
                                                             int(row["node_to"]))
    assert result.tracking == (row["state"] == "tracking")
    assert result.tracked == int(row["tracked"])
    assert (result.tracked_previous, result.tracked_current, result.tracked_next) == (
        int(row["tracked_previous"]), int(row["tracked_current"]), int(row["tracked_next"]))
    assert (result.resumed, result.dropped, result.transition) == (int(row["resumed"]), int(row["dropped"]),
                                                                  int(row["transition"]))
    assert f"{result.confidence:.5f}" == row["confidence"]
    assert int(result.evidence) == int(row["evidence"]) and result.belief_arc == int(row["belief_arc"])
    assert f"{result.steering if result.steering is not None else 0.0:.5f}" == row["steering"]
    position = result.position_on_arc if result.position_on_arc is not None else 0.0
    assert f"{position:.4f}" == row["position_on_arc"]
    assert result.key_images_matched == int(row["key_images_matched"])
    assert result.seconds > 0
    # The metric offset from the taught path (the map stores the camera's height).
    path_columns = ("lateral_m", "lateral_sigma_m", "heading_error_rad", "along_m", "to_next_m", "curvature_ahead",
                    "frame_lateral_m", "frame_lateral_sigma_m", "heading_sigma_rad", "along_sigma_m",
                    "heading_per_lateral")
    if row["lateral_m"] == "":
        assert result.path is None
    else:
        p = result.path
        assert [f"{p.lateral_m:.4f}", f"{p.lateral_sigma_m:.4f}", f"{p.heading_error_rad:.5f}", f"{p.along_m:.3f}",
                f"{p.to_next_m:.3f}", f"{p.curvature_ahead:.5f}", f"{p.frame_lateral_m:.4f}",
                f"{p.frame_lateral_sigma_m:.4f}", f"{p.heading_sigma_rad:.5f}",
                f"{p.along_sigma_m:.3f}", f"{p.heading_per_lateral:.5f}"] == [row[column] for column in path_columns]


def test_localizer_gives_the_states_and_arcs_of_repeat(drives):
    rows = read_csv(drives.run)
    frames = list(retrace.Sequence(drives.repeat))
    assert len(rows) == len(frames)
    # The drive has every state, so that agreeing is not trivial.
    assert {row["state"] for row in rows} == {"tracking", "lost", "relocalizing"}
    assert len({row["arc"] for row in rows}) >= 5
    assert sum(row["lateral_m"] != "" for row in rows) >= len(rows) // 2

    localizer = retrace.Localizer(drives.map)
    results = [localizer.process(frame) for frame in frames]
    for result, row in zip(results, rows):
        assert_same_as_run_csv(result, row)
    assert localizer.state == rows[-1]["state"]
    # The repeat drive runs REPEAT_OFFSET m to the right of the taught one (positive lateral_m: to the right).
    lateral = np.median([r.path.lateral_m for r in results if r.path is not None])
    assert REPEAT_OFFSET - 1.5 < lateral < REPEAT_OFFSET + 1.5


def test_localizer_takes_numpy_images_gray_or_bgr(drives):
    rows = read_csv(drives.run)[:20]
    frames = [f for _, f in zip(range(len(rows)), retrace.Sequence(drives.repeat))]
    gray = retrace.Localizer(retrace.Map(drives.map, load_images=False))
    bgr = retrace.Localizer(str(drives.map), camera=retrace.Camera.read(drives.repeat / "camera.yaml"))
    for frame, row in zip(frames, rows):
        image = frame.image
        assert_same_as_run_csv(gray.process(image), row)  # frames numbered 0, 1, ... as in run.csv
        # BGR with the gray value in every channel, as a strided view of a BGRA array (copied where needed).
        colour = np.repeat(image[:, :, None], 4, axis=2)[:, :, :3]
        assert not colour.flags.c_contiguous
        assert_same_as_run_csv(bgr.process(colour), row)


def test_localizer_releases_the_gil(drives):
    # While one thread localizes a frame, another one runs Python code. The first frame is found by retrieval
    # (wide-baseline matching against the key-images); with SIFT extracted from the frame and every key-image it
    # verifies (sift_relocalization, as before the stored binary key-points) that is hundreds of milliseconds in one
    # call.
    image = next(iter(retrace.Sequence(drives.repeat))).image
    localizer = retrace.Localizer(drives.map, sift_relocalization=True)
    ticks = []
    stop = threading.Event()

    def count():
        while not stop.is_set():
            ticks.append(time.monotonic())
            stop.wait(0.001)

    counter = threading.Thread(target=count)
    counter.start()
    try:
        time.sleep(0.01)
        start = time.monotonic()
        result = localizer.process(image)
        end = time.monotonic()
    finally:
        stop.set()
        counter.join()
    # Retrieval verified key-images in this call (with the stricter checks of relocalization over the whole map this
    # frame, 3 m beside the taught drive, is no longer localized at once; the call is as long either way).
    assert result.key_images_matched > 0 and end - start > 0.1
    # Held, the GIL would let the counter tick once or twice in the call; released, it ticks every millisecond or so.
    during = sum(start < t < end for t in ticks)
    assert during > 20, (during, end - start)


def test_localizer_errors(drives, tmp_path):
    localizer = retrace.Localizer(drives.map)
    with pytest.raises(retrace.InputError, match=r"^frame_000000: image is 100x80 8-bit gray expected 320x240$"):
        localizer.process(np.zeros((80, 100), np.uint8))
    with pytest.raises(retrace.InputError, match=r"^left.png: image is"):
        localizer.process(np.zeros((80, 100), np.uint8), name="left.png")
    for bad in (np.zeros((240, 320), np.float64), np.zeros((240, 320), np.uint16)):
        with pytest.raises(ValueError, match="expected dtype uint8"):
            localizer.process(bad)
    for bad in (np.zeros(320, np.uint8), np.zeros((240, 320, 2), np.uint8), np.zeros((0, 320), np.uint8)):
        with pytest.raises(ValueError, match=r"expected a non-empty gray image \(H, W\) or a BGR image"):
            localizer.process(bad)
    with pytest.raises(TypeError, match="expected a numpy array"):
        localizer.process([[0, 1], [2, 3]])
    # A start arc the map does not have: the command line's message.
    with pytest.raises(retrace.InputError) as error:
        retrace.Localizer(drives.map, start_arc=99)
    assert str(error.value) == cli_error("repeat", "--map", drives.map, "--sequence", drives.repeat, "--start-arc",
                                         "99", "--output", tmp_path / "run.csv", "--no-progress")
    # Another calibration than the map's is refused, not bent to fit.
    camera = retrace.Camera.read(drives.teach / "camera.yaml")
    fx = f"{camera.focal_length:.10g}"[:8]
    narrow = retrace.Camera.from_yaml(camera.to_yaml().replace(fx, "230.0000"), "narrow")
    assert narrow.focal_length == pytest.approx(230.0)
    with pytest.raises(retrace.InputError, match="^camera: differs from the map's camera"):
        retrace.Localizer(drives.map, camera=narrow)
    # The same camera at twice the resolution is the map's camera (frames are resized to the map's width).
    assert retrace.Localizer(drives.map, camera=camera.scaled(2.0)).camera.to_yaml() == camera.to_yaml()
    with pytest.raises(retrace.InputError, match="localizer options"):
        retrace.Localizer(drives.map, max_bad_frames=0)
    with pytest.raises(retrace.InputError, match="start_retrieval_shortlist"):
        retrace.Localizer(drives.map, start_retrieval_shortlist=-1)
