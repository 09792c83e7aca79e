"""scripts/closed-loop-score on a drive whose figures are known: three runs written by hand in the layout of
`retrace sim drive` (drive.csv, drive.log), scored, and the score checked against what the rows say."""

import csv
import json
import subprocess
import sys

from conftest import SOURCE_DIR

COLUMNS = ["frame", "x", "z", "state", "deviation", "steered_lateral_m", "true_lateral_m"]


def write_run(folder, deviations, steered, reached_end=True):
    """One run: the camera drives 1 m per frame along x, `deviations[i]` from the taught path, the law steering by
    `steered[i]` (None: not by the metric path) against a true offset equal to the deviation."""
    folder.mkdir(parents=True)
    with open(folder / "drive.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(COLUMNS)
        for i, (d, s) in enumerate(zip(deviations, steered)):
            writer.writerow([i, float(i), 0.0, "tracking", d, "" if s is None else s, d])
    ending = "reached the end of the taught route" if reached_end else "stood still too long (lost)"
    (folder / "drive.log").write_text(
        f"drive (path): {len(deviations)} frames; {ending}\n"
        "after the first 10 m: 30 frames, lateral deviation RMS 0.050 m, 95th percentile 0.090 m, max 0.120 m\n")


def test_scores_a_drive(tmp_path):
    frames = 41
    # From 1.5 m beside: within 0.2 m from frame 11 on (11 m driven), 0.15 m at most after 15 m.
    converging = [1.5 - 0.12 * i if i < 12 else (0.15 if i == 20 else 0.05) for i in range(frames)]
    steady = [0.05] * frames
    # The law steered by the truth plus 0.01 m in frames 0-19, plus 0.2 m in frames 20-39, and not at all in frame 40.
    steered = [0.05 + (0.01 if i < 20 else 0.2) for i in range(frames - 1)] + [None]
    write_run(tmp_path / "path", steady, steered)
    write_run(tmp_path / "eq10", steady, [None] * frames, reached_end=False)
    write_run(tmp_path / "path1.5", converging, [None] * frames)
    script = SOURCE_DIR / "scripts" / "closed-loop-score"
    result = subprocess.run([sys.executable, str(script), "drive", str(tmp_path), "--name", "made", "--start", "1",
                             "--top-speed", "8", "--rate", "10"], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("made")
    score = json.loads((tmp_path / "score.json").read_text())
    path, eq10, beside = score["runs"]["path"], score["runs"]["eq10"], score["runs"]["path1.5"]
    # Read from drive.log, not recomputed.
    assert (path["rms_m"], path["p95_m"], path["max_m"]) == (0.05, 0.09, 0.12)
    assert path["reached_end"] and not eq10["reached_end"]
    assert beside["first_within_m"] == 11.0
    assert abs(beside["max_after_15m"] - 0.15) < 1e-12
    assert path["driven_m"] == 40.0
    # 40 frames steered by the metric path: 20 off by 0.01 m, 20 by 0.2 m.
    assert abs(path["steered_error_p50_m"] - 0.2) < 1e-9
    assert abs(path["steered_error_p95_m"] - 0.2) < 1e-9
    assert eq10["steered_error_p95_m"] is None

    summary = subprocess.run([sys.executable, str(script), "summary", str(tmp_path)], capture_output=True, text=True)
    assert summary.returncode == 0, summary.stderr
    assert "steered offset error, 95th percentile per drive: median 0.200, worst 0.200 m" in summary.stdout
    assert "from 1.5 m within 0.2 m after <= 15 m and staying within it in 1/1" in summary.stdout
