"""retrace.Map and retrace.Camera against `retrace inspect --json` and `retrace camera-info` on the same files."""

import json

import numpy as np
import pytest
import retrace

from conftest import cli_error, run_cli


def test_map_reads_what_inspect_reports(drives):
    report = json.loads(run_cli("inspect", "--map", drives.map, "--json").stdout)
    m = retrace.Map(drives.map)
    assert m.complete
    assert m.metadata == report["metadata"]

    assert [n.id for n in m.nodes] == [n["id"] for n in report["nodes"]]
    frames = {f.index: f.image for f in retrace.Sequence(drives.teach)}
    for node, expected in zip(m.nodes, report["nodes"]):
        assert node.source_frame == expected["source_frame"]
        assert node.image_name == expected["image"]
        assert node.timestamp == pytest.approx(expected["timestamp"])
        assert node.num_features == expected["features"]
        assert node.route == expected["route"] == 0
        assert node.feature_ids.shape == (expected["features"],)
        assert node.feature_positions.shape == (expected["features"], 2)
        # The key-image: 8-bit gray at the map camera's size, and the frame it was taken from (stored as JPEG).
        image = node.image
        assert image.dtype == np.uint8 and image.shape == (m.camera.height, m.camera.width)
        assert np.abs(image.astype(int) - frames[node.source_frame].astype(int)).mean() < 3.0

    assert [a.id for a in m.arcs] == [a["id"] for a in report["arcs"]]
    for arc, expected in zip(m.arcs, report["arcs"]):
        assert (arc.node_from, arc.node_to, arc.kind) == (expected["from"], expected["to"], expected["kind"])
        assert arc.sigma_p == pytest.approx(expected["sigma_p"], rel=1e-12)
        assert arc.similarity == pytest.approx(expected["similarity"], rel=1e-12) and 0 < arc.similarity <= 1
        assert arc.num_features == expected["features"] == len(arc.feature_ids) == len(arc.points)
        np.testing.assert_allclose(arc.rotation.ravel(), expected["R"], rtol=0, atol=1e-12)
        np.testing.assert_allclose(arc.translation, expected["t"], rtol=0, atol=1e-12)
        np.testing.assert_allclose(arc.to_from_from[:3, :3], arc.rotation)
        # The arc's features are seen in both of its key-images.
        assert set(arc.feature_ids) <= set(m.node(arc.node_from).feature_ids)
        assert set(arc.feature_ids) <= set(m.node(arc.node_to).feature_ids)
        assert arc.id in [a.id for a in m.arcs_from(arc.node_from)]
        assert arc.id in [a.id for a in m.arcs_to(arc.node_to)]

    assert [(s.node, s.arc_in, s.arc_out) for s in m.scales] == [
        (s["node"], s["arc_in"], s["arc_out"]) for s in report["scales"]]
    np.testing.assert_allclose([s.scale for s in m.scales], [s["scale"] for s in report["scales"]], rtol=1e-12)

    # Without images the geometry is the same.
    light = retrace.Map(str(drives.map), load_images=False)
    assert light.nodes[0].image is None and len(light.arcs) == len(m.arcs)
    with pytest.raises(KeyError):
        m.arc(10**6)


def test_nodes_outlive_their_map_object(drives):
    node = retrace.Map(drives.map).nodes[-1]  # the Map object itself is gone
    assert node.image.shape == (240, 320)


def test_camera_matches_camera_info(drives):
    camera = retrace.Camera.read(drives.teach / "camera.yaml")
    info = run_cli("camera-info", "--camera", drives.teach / "camera.yaml").stdout
    assert f"model: {camera.model}" in info and f"image size: {camera.width}x{camera.height}" in info
    assert f"focal length: {camera.focal_length:.4f} px" in info
    # The map stores the camera it was taught with, and the simulator renders with that camera.
    stored = retrace.Map(drives.map, load_images=False).camera
    assert stored.to_yaml() == camera.to_yaml()
    assert retrace.Simulator(frames=1, width=320, height=240, seed=3).camera.to_yaml() == camera.to_yaml()
    # Projection and its inverse agree.
    pixels = np.array([[10.0, 20.0], [160.0, 120.0], [300.5, 230.0]])
    bearings = camera.unproject(pixels)
    np.testing.assert_allclose(np.linalg.norm(bearings, axis=1), 1.0)
    np.testing.assert_allclose(camera.project(bearings * 5.0), pixels, atol=1e-6)
    assert np.isnan(camera.project([0.0, 0.0, -1.0])).all()  # behind the camera
    assert camera.scaled(0.5).width == 160


def test_bad_files_raise_the_command_lines_errors(drives, tmp_path):
    garbage = tmp_path / "garbage.db"
    garbage.write_bytes(b"garbage, not a map")
    truncated = tmp_path / "truncated.db"
    truncated.write_bytes(drives.map.read_bytes()[:3000])
    for path in (garbage, truncated, tmp_path / "missing.db"):
        with pytest.raises(retrace.InputError) as error:
            retrace.Map(path)
        assert str(error.value) == cli_error("inspect", "--map", path)
        assert str(path) in str(error.value) and error.value.source == str(path)
        assert isinstance(error.value, ValueError)
        with pytest.raises(retrace.InputError, match=str(path)):
            retrace.Localizer(path)

    with pytest.raises(retrace.InputError) as error:
        retrace.Camera.read(garbage)
    assert str(error.value) == cli_error("camera-info", "--camera", garbage)
    with pytest.raises(TypeError):
        retrace.Map(42)


def test_a_kitti_colour_folder_names_its_camera(tmp_path):
    # KITTI's colour download: image_2 only, and calib.txt with P0 to P3 (here P2 differs, to tell them apart).
    images = tmp_path / "image_2"
    images.mkdir()
    for i in range(2):
        rgb = np.zeros((48, 64, 3), np.uint8)
        rgb[:, :, 1] = 40 + i
        write_png(images / f"{i:06d}.png", rgb)
    (tmp_path / "times.txt").write_text("0\n0.1\n")
    (tmp_path / "calib.txt").write_text("P0: 50 0 32 0 0 50 24 0 0 0 1 0\nP2: 60 0 30 3 0 61 25 0 0 0 1 0\n")
    sequence = retrace.Sequence(tmp_path)
    assert sequence.calibration_camera == "P2"
    frames = list(sequence)
    assert len(frames) == 2 and frames[1].image.ndim == 2
    camera = retrace.Camera.read(sequence.calibration_file, image_size=sequence.image_size,
                                 camera=sequence.calibration_camera)
    assert camera.focal_length == pytest.approx(60.5)  # (fx + fy) / 2 of P2
    first = retrace.Camera.read(sequence.calibration_file, image_size=sequence.image_size)
    assert first.focal_length == pytest.approx(50.0)  # P0


def write_png(path, rgb):
    """Writes an RGB PNG with Pillow (Debian's python3-pil)."""
    from PIL import Image
    Image.fromarray(rgb).save(path)
