"""The examples run as a researcher would run them, on small drives, and say what the bindings compute."""

import os
import re
import subprocess
import sys

import matplotlib.image
import retrace

from conftest import SOURCE_DIR, read_csv

EXAMPLES = SOURCE_DIR / "examples"


def run_example(name, *args):
    environment = dict(os.environ, PYTHONPATH=os.path.dirname(retrace.__file__))
    result = subprocess.run([sys.executable, str(EXAMPLES / name), *map(str, args)], capture_output=True, text=True,
                            env=environment)
    assert result.returncode == 0, result.stderr
    return result.stdout


def test_localize_sequence_example(drives, tmp_path):
    # A folder of the repeat drive's first 30 images: the start of the command line's run (frames are localized
    # one after the other, whatever follows them).
    folder = tmp_path / "images"
    folder.mkdir()
    for image in sorted((drives.repeat / "image_0").glob("*.png"))[:30]:
        (folder / image.name).symlink_to(image)
    plot = tmp_path / "localization.png"
    output = run_example("localize_sequence.py", drives.map, folder, plot)
    rows = read_csv(drives.run)[:30]
    assert {row["state"] for row in rows} == {"tracking", "lost", "relocalizing"}
    tracking = sum(row["state"] == "tracking" for row in rows)
    assert f"{len(rows)} frames: {tracking} tracking, {len(rows) - tracking} lost or relocalizing" in output
    assert matplotlib.image.imread(plot).shape[:2] == (500, 900)


def test_teach_simulated_drive_example(tmp_path):
    output = run_example("teach_simulated_drive.py", tmp_path, "--frames", 30)
    taught = retrace.Map(tmp_path / "town.db")
    assert taught.complete and len(taught.arcs) >= 3
    assert re.findall(r"^  node (\d+):", output, re.M) == [str(n.id) for n in taught.nodes]
    assert re.findall(r"^  arc (\d+):", output, re.M) == [str(a.id) for a in taught.arcs]
    assert matplotlib.image.imread(tmp_path / "key_image.png").ndim == 3
