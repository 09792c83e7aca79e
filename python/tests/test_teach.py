"""retrace.Teacher against `retrace teach` on the same frames: the same map, written the same safe way."""

import numpy as np
import pytest
import retrace

from conftest import CAMERA_HEIGHT, cli_error


def assert_same_map(a, b):
    """Same nodes, arcs and scales (the geometry to the bit: the same computation on the same frames)."""
    assert [(n.id, n.source_frame, n.image_name) for n in a.nodes] == [
        (n.id, n.source_frame, n.image_name) for n in b.nodes]
    for x, y in zip(a.nodes, b.nodes):
        assert x.timestamp == pytest.approx(y.timestamp, abs=1e-6)
        np.testing.assert_array_equal(x.feature_ids, y.feature_ids)
        np.testing.assert_array_equal(x.feature_positions, y.feature_positions)
        np.testing.assert_array_equal(x.image, y.image)
    assert [(r.id, r.node_from, r.node_to, r.kind, r.num_features) for r in a.arcs] == [
        (r.id, r.node_from, r.node_to, r.kind, r.num_features) for r in b.arcs]
    for x, y in zip(a.arcs, b.arcs):
        assert x.sigma_p == y.sigma_p
        np.testing.assert_array_equal(x.to_from_from, y.to_from_from)
        np.testing.assert_array_equal(x.feature_ids, y.feature_ids)
        np.testing.assert_array_equal(x.points, y.points)
    assert [(s.node, s.arc_in, s.arc_out, s.scale) for s in a.scales] == [
        (s.node, s.arc_in, s.arc_out, s.scale) for s in b.scales]


def test_teacher_writes_the_map_teach_writes(drives, tmp_path):
    camera = retrace.Camera.read(drives.teach / "camera.yaml")
    path = tmp_path / "python.db"
    with retrace.Teacher(path, camera, source=str(drives.teach), camera_height=CAMERA_HEIGHT) as teacher:
        # numpy images with the names and timestamps the command line reads from the folder
        for frame in retrace.Sequence(drives.teach):
            teacher.add_frame(frame.image, timestamp=frame.timestamp, name=frame.name)
        assert not teacher.finished and not path.exists()  # staged in python.db.incomplete until finished
    assert teacher.finished and path.exists()
    assert not (tmp_path / "python.db.incomplete").exists() and not (tmp_path / "python.db.lock").exists()

    ours, theirs = retrace.Map(path), retrace.Map(drives.map)
    assert len(ours.arcs) >= 5
    assert_same_map(ours, theirs)
    # The settings repeat reads from the map, and the camera.
    for key in ("reference_width", "smoothing_sigma_px", "r_p", "min_features", "max_residual", "width", "method",
                "teach_state", "source_sequence", "camera_height"):
        assert ours.metadata[key] == theirs.metadata[key], key
    assert ours.camera.to_yaml() == theirs.camera.to_yaml()
    stats = teacher.statistics
    assert stats["frames"] == len(retrace.Sequence(drives.teach))
    assert stats["key_images"] == stats["nodes"] == len(ours.nodes) and stats["arcs"] == len(ours.arcs)
    with pytest.raises(RuntimeError, match="finished"):
        teacher.add_frame(np.zeros((240, 320), np.uint8))


def test_teacher_keeps_the_command_lines_safety(drives, tmp_path):
    camera = retrace.Camera.read(drives.teach / "camera.yaml")
    frames = [f for _, f in zip(range(12), retrace.Sequence(drives.teach))]
    path = tmp_path / "route.db"
    path.write_bytes(drives.map.read_bytes())
    before = path.read_bytes()

    # An existing map is not replaced without overwrite: the command line's message.
    with pytest.raises(retrace.InputError) as error:
        retrace.Teacher(path, camera)
    assert str(error.value) == cli_error("teach", "--sequence", drives.teach, "--map", path, "--no-progress")

    # One teach at a time per map; an abandoned teach (an exception in the block) leaves the old map untouched and
    # what it taught in route.db.incomplete, marked incomplete.
    with pytest.raises(ZeroDivisionError):
        with retrace.Teacher(path, camera, overwrite=True) as teacher:
            for frame in frames:
                teacher.add_frame(frame)
            with pytest.raises(retrace.InputError, match="route.db"):
                retrace.Teacher(path, camera, overwrite=True)
            1 / 0
    assert path.read_bytes() == before
    incomplete = retrace.Map(tmp_path / "route.db.incomplete")
    assert not incomplete.complete and incomplete.metadata["teach_state"] == "incomplete"
    assert len(incomplete.nodes) >= 1

    # A frame of another size is the Teacher's one-line error naming the frame; another dtype a ValueError.
    teacher = retrace.Teacher(tmp_path / "other.db", camera)
    with pytest.raises(retrace.InputError, match=r"^frame_000000: image is 100x80"):
        teacher.add_frame(np.zeros((80, 100), np.uint8))
    with pytest.raises(ValueError, match="dtype uint8"):
        teacher.add_frame(np.zeros((240, 320), np.float32))
    with pytest.raises(retrace.InputError, match="teach options"):
        retrace.Teacher(tmp_path / "bad.db", camera, min_features=-1)
