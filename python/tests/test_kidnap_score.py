"""scripts/kidnap-score on runs whose figures are known: the CSVs and logs of `retrace bench kidnap` and of the whole
repeat written by hand in the layout scripts/kidnap-validation leaves, scored, and the lines checked against them."""

import subprocess
import sys

from conftest import SOURCE_DIR

SCRIPT = SOURCE_DIR / "scripts" / "kidnap-score"
HEADER = "start,frame,state,arc,correct,wrong,ms,key_images_matched,confidence\n"


def write_seed(folder, name, starts, cpu_median, cpu_p95):
    """One bench run: `starts` is a list of (start frame, [(state, correct, wrong) per frame])."""
    rows = []
    for start, frames in starts:
        for k, (state, correct, wrong) in enumerate(frames):
            rows.append(f"{start},{start + k},{state},7,{correct},{wrong},12.5,3,0.99\n")
    (folder / f"{name}.csv").write_text(HEADER + "".join(rows))
    (folder / f"{name}.log").write_text(
        f"kidnap: {len(starts)} starts on a map of 50 key-images (49 arcs), 3 frames each: ...\n"
        f"kidnap: first frame 40.0 ms median, 90.0 ms 95th percentile, 120.0 ms max (wall); CPU {cpu_median} ms "
        f"median, {cpu_p95} ms 95th percentile; frames not localized: 1 (30.0 ms median)\n"
        "kidnap: peak memory 250 MB\n")


TRACKED = ("tracking", 1, 0)
LOST = ("relocalizing", 0, 0)
WRONG = ("tracking", 0, 1)


def make_runs(folder, lost_ms=15.5, lost_tracking=0, memory_kb=290000):
    # Seed 1: four starts, start frame 100 drawn twice (once localized at once, once only at its third frame).
    write_seed(folder, "kidnap-seed1", [(100, [TRACKED, TRACKED, TRACKED]), (100, [LOST, LOST, TRACKED]),
                                        (250, [LOST, LOST, LOST]), (300, [TRACKED, TRACKED, TRACKED])], 30.0, 80.0)
    # Seed 2: two starts, one with a wrong frame after it was localized.
    write_seed(folder, "kidnap-seed2", [(10, [TRACKED, WRONG, TRACKED]), (20, [TRACKED, TRACKED, TRACKED])], 50.0,
               120.0)
    (folder / "lost.log").write_text(
        f"kidnap: lost in lost (60 frames of a drive elsewhere): 60 relocalizing frames, 20.0 ms median, 30.0 ms 95th "
        f"percentile (wall; CPU {lost_ms} ms median); {lost_tracking} frames reported tracking\n")
    (folder / "repeat.log").write_text(
        "topological ground truth: 6305 frames: 100.0% correct, 0 wrong (0 by >= 2 arcs), 0 lost (0.0%)\n"
        f"\tMaximum resident set size (kbytes): {memory_kb}\n")


def score(folder, *args):
    result = subprocess.run([sys.executable, str(SCRIPT), str(folder), *args], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    return result.stdout


def test_counts_every_start_drawn_and_marks_the_targets(tmp_path):
    make_runs(tmp_path)
    out = score(tmp_path, "--seeds", "1", "2", "--repeat")
    lines = {line.split()[0] + (" " + line.split()[1] if line.startswith("seed") else ""): line.split()
             for line in out.splitlines() if line.startswith(("seed", "total"))}
    # Seed 1: 4 starts, 2 localized at the first frame, 3 within the three frames, none wrong.
    assert lines["seed 1"][2:7] == ["4", "50.0", "75.0", "0", "0"]
    # Seed 2: 2 starts, both at the first frame, one wrong frame in one start.
    assert lines["seed 2"][2:7] == ["2", "100.0", "100.0", "1", "1"]
    assert lines["seed 2"][7:9] == ["50.0", "120.0"]
    # Totals: 6 starts, 4 / 6 and 5 / 6; the times are the medians of the seeds'.
    assert lines["total"][1:5] == ["6", "66.7", "83.3", "1"]
    assert lines["total"][5:7] == ["40.0", "100.0"]
    assert "localized at the first frame >= 95 %: 66.7 %  MISSED" in out
    assert "wrong frames 0: 1  MISSED" in out
    assert "first frame CPU median <= 50 ms: 40.0 ms  met" in out
    assert "first frame CPU 95th percentile <= 100 ms: 100.0 ms  met" in out
    assert "relocalizing frame while lost, CPU median <= 20 ms: 15.5 ms  met" in out
    assert "peak memory of the whole repeat <= 300 MB: 283 MB  met" in out
    assert "over 2 seed(s) only" in out


def test_reports_what_the_lost_frames_and_the_memory_miss(tmp_path):
    make_runs(tmp_path, lost_ms=24.0, lost_tracking=2, memory_kb=400000)
    out = score(tmp_path, "--seeds", "1", "1", "--repeat")
    assert "relocalizing frame while lost, CPU median <= 20 ms: 24.0 ms  MISSED" in out
    assert "frames of another town reported tracking 0: 2  MISSED" in out
    assert "peak memory of the whole repeat <= 300 MB: 391 MB  MISSED" in out


def test_a_missing_run_is_an_error_naming_the_folder(tmp_path):
    make_runs(tmp_path)
    result = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path), "--seeds", "1", "3"], capture_output=True,
                            text=True)
    assert result.returncode != 0
    assert "kidnap-score: cannot score the runs in" in result.stderr and "kidnap-seed3.csv" in result.stderr
