"""scripts/validation-score's judgement of a taught map's links, on maps and poses written by hand: a loop link onto a
key-image the drive has just passed is false (it goes backwards), a loop that comes back to the start is not."""

import json
import math
import subprocess
import sys

from conftest import SOURCE_DIR

SCRIPT = SOURCE_DIR / "scripts" / "validation-score"


def yaw_matrix(yaw):
    """world_from_cam of a camera looking along +z turned by `yaw` about the vertical (y) axis, row-major."""
    c, s = math.cos(yaw), math.sin(yaw)
    return [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]


def write_poses(path, poses):
    """poses: (yaw, (x, y, z)) per frame, as KITTI lines of [R | c]."""
    lines = []
    for yaw, c in poses:
        r = yaw_matrix(yaw)
        lines.append(" ".join(f"{v:.9f}" for row in range(3) for v in (*r[row], c[row])))
    path.write_text("\n".join(lines) + "\n")


def relative(poses, a, b):
    """to_from_from of frames a -> b (R row-major, unit t)."""
    ya, ca = poses[a]
    yb, cb = poses[b]
    ra, rb = yaw_matrix(ya), yaw_matrix(yb)
    r = [[sum(rb[k][i] * ra[k][j] for k in range(3)) for j in range(3)] for i in range(3)]
    d = [x - y for x, y in zip(ca, cb)]
    t = [sum(rb[k][i] * d[k] for k in range(3)) for i in range(3)]
    n = math.sqrt(sum(x * x for x in t))
    return [v for row in r for v in row], [x / n for x in t]


def score(tmp_path, poses, key_frames, loop_to):
    """Scores a map whose key-images stand at `key_frames`, chained by tracked arcs, plus a loop arc from the last
    key-image to key-image `loop_to` with its true geometry. Returns the drive's false links."""
    write_poses(tmp_path / "poses.txt", poses)
    nodes = [{"id": i, "source_frame": f} for i, f in enumerate(key_frames)]
    arcs = []
    for i in range(len(key_frames) - 1):
        r, t = relative(poses, key_frames[i], key_frames[i + 1])
        arcs.append({"id": i, "from": i, "to": i + 1, "kind": "tracking", "R": r, "t": t})
    r, t = relative(poses, key_frames[-1], key_frames[loop_to])
    arcs.append({"id": len(arcs), "from": len(key_frames) - 1, "to": loop_to, "kind": "loop", "R": r, "t": t})
    (tmp_path / "map.json").write_text(json.dumps({"nodes": nodes, "arcs": arcs}))
    (tmp_path / "run.csv").write_text("frame,state,ms\n0,tracking,10.0\n")
    (tmp_path / "run.truth.csv").write_text("frame,correct,lost,error\n0,1,0,0\n")
    subprocess.run([sys.executable, str(SCRIPT), "drive", str(tmp_path), "--name", "d", "--group", "g", "--offset", "0",
                    "--speed", "8", "--rate", "10", "--teach-poses", str(tmp_path / "poses.txt")],
                   check=True, capture_output=True, text=True)
    return json.loads((tmp_path / "score.json").read_text())["false_links"]


def test_a_loop_onto_a_key_image_just_passed_is_false(tmp_path):
    # A straight drive along +z, 1 m per frame; the last key-image (frame 40) linked to key-image 1 (frame 25),
    # 15 m behind it and looking the same way: the views and the geometry are right, the topology is not.
    poses = [(0.0, (0.0, 0.0, float(k))) for k in range(41)]
    false = score(tmp_path, poses, [0, 12, 25, 40], loop_to=1)
    assert len(false) == 1 and "goes backwards" in false[0]


def test_a_loop_back_to_the_start_is_true(tmp_path):
    # Around a circle of radius 20 m, 2 degrees per frame, and 2 frames short of where it started: the last
    # key-image links to the first, which lies ahead of it.
    poses = []
    for k in range(179):
        a = math.radians(2.0 * k)
        poses.append((a, (20.0 * (1.0 - math.cos(a)), 0.0, 20.0 * math.sin(a))))
    false = score(tmp_path, poses, list(range(0, 178, 20)) + [178], loop_to=0)
    assert false == []
