"""Shared fixtures of the Python bindings' tests: small simulated drives rendered, taught and repeated by the
`retrace` command line, which the bindings' results are checked against.

ctest (python/bindings_test) sets PYTHONPATH to build/python and RETRACE_BINARY to the built `retrace`; run by hand,
the tests find both in the build folder next to the sources:
    /usr/bin/python3 -m pytest python/tests
"""

import csv
import os
import pathlib
import subprocess
import sys

import pytest

SOURCE_DIR = pathlib.Path(os.environ.get("RETRACE_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
BUILD_DIR = SOURCE_DIR / "build"

try:
    import retrace  # noqa: F401
except ImportError:
    sys.path.insert(0, str(BUILD_DIR / "python"))

# The drives: a short stretch of one seeded town at 320x240. The repeat drive runs REPEAT_OFFSET m to the side of
# the taught one under another sun, so that it has tracking, lost and relocalizing frames to compare (3 m stopped
# giving relocalizing frames once a start with one look-alike check per map size localized them).
FRAMES = 60
SIZE = ["--width", "320", "--height", "240"]
SEED = ["--seed", "3"]
# The simulated car's camera height above the ground (sim/vehicle.h): teach stores it, repeat then reports the
# camera's offset from the taught path in metres.
CAMERA_HEIGHT = 1.5
REPEAT_OFFSET = 4.0


def run_cli(*args, check=True):
    """Runs the `retrace` binary; returns the completed process (stdout, stderr as text)."""
    binary = os.environ.get("RETRACE_BINARY", str(BUILD_DIR / "bin" / "retrace"))
    result = subprocess.run([binary, *map(str, args)], capture_output=True, text=True)
    if check and result.returncode != 0:
        raise AssertionError(f"retrace {' '.join(map(str, args))} failed: {result.stderr}")
    return result


def cli_error(*args):
    """The one-line message `retrace` prints for a failing command, without its 'retrace: error: ' prefix."""
    result = run_cli(*args, check=False)
    assert result.returncode == 1, result.stderr
    lines = [line for line in result.stderr.splitlines() if line.startswith("retrace: error: ")]
    assert len(lines) == 1, result.stderr
    return lines[0][len("retrace: error: "):]


def read_csv(path):
    with open(path, newline="") as file:
        return list(csv.DictReader(file))


class Drives:
    """The folder of the command line's drives, maps and runs."""

    def __init__(self, root):
        self.root = root
        self.teach = root / "teach"    # KITTI layout written by `retrace sim render`
        self.repeat = root / "repeat"
        self.map = root / "cli.db"      # `retrace teach` on the teach drive
        self.run = root / "run.csv"     # `retrace repeat` of the repeat drive in that map


@pytest.fixture(scope="session")
def drives(tmp_path_factory):
    root = tmp_path_factory.mktemp("drives")
    d = Drives(root)
    run_cli("sim", "render", "--out", d.teach, "--frames", FRAMES, *SIZE, *SEED, "--quiet")
    run_cli("sim", "render", "--out", d.repeat, "--frames", FRAMES, *SIZE, *SEED, "--variant", "repeat",
            "--lateral-offset", REPEAT_OFFSET, "--quiet")
    run_cli("teach", "--sequence", d.teach, "--map", d.map, "--camera-height", CAMERA_HEIGHT, "--no-progress")
    run_cli("repeat", "--map", d.map, "--sequence", d.repeat, "--output", d.run, "--no-progress")
    return d
