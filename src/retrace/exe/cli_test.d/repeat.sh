# shellcheck shell=bash
# CLI checks of `retrace repeat` (sourced by cli_test.sh: $bin, $data, $tmp, expect).

expect repeat-missing-map 1 "^retrace: error: .*no_such_map.db" -- \
  "$bin" repeat --map "$tmp/no_such_map.db" --sequence "$tmp" --output "$tmp/run.csv"
expect repeat-needs-output 106 "--output is required" -- "$bin" repeat --map a.db --sequence b

if [[ -d $data/kitti07 ]]; then
  k=$data/kitti07
  # Pseudo-repeat (design §9): teach on the even frames, repeat on the odd ones; every frame on the right arc.
  "$bin" teach --sequence "$k" --map "$tmp/repeat_route.db" --every 2 --no-progress >/dev/null 2>&1
  expect repeat-kitti-odd-frames 0 "topological ground truth: 80 frames: 100\.0% correct, 0 wrong \(0 by >= 2 arcs\), 0 lost" -- \
    "$bin" repeat --map "$tmp/repeat_route.db" --sequence "$k" --every 2 --offset 1 --start-arc 0 \
    --output "$tmp/repeat_run.csv" --evaluate --no-progress
  # One CSV row per frame after the header, states and arcs filled in.
  expect repeat-csv-rows 0 "^81 tracking$" -- \
    bash -c "echo \$(wc -l < '$tmp/repeat_run.csv') \$(sed -n 2p '$tmp/repeat_run.csv' | cut -d, -f4)"
  expect repeat-bad-start-arc 1 "^retrace: error: start arc: the map has no arc 99$" -- \
    "$bin" repeat --map "$tmp/repeat_route.db" --sequence "$k" --start-arc 99 --output "$tmp/r.csv" --no-progress
fi

if [[ -d $data/kitti07 && -f $tmp/repeat_route.db ]]; then
  # --evaluate writes the per-frame ground truth next to the run: one row per frame, every odd frame correct.
  expect repeat-truth-csv 0 "^81 80$" -- \
    bash -c "echo \$(wc -l < '$tmp/repeat_run.truth.csv') \$(awk -F, 'NR > 1 && \$5 == 1' '$tmp/repeat_run.truth.csv' | wc -l)"
  # The map stores teach's pre-smoothing; a map whose stored value is garbage is rejected with the key named.
  cp "$tmp/repeat_route.db" "$tmp/repeat_bad_meta.db"
  sqlite3 "$tmp/repeat_bad_meta.db" "UPDATE metadata SET value = 'abc' WHERE key = 'smoothing_sigma_px'" 2>/dev/null &&
    expect repeat-bad-metadata 1 "^retrace: error: .*repeat_bad_meta.db: metadata smoothing_sigma_px is not a number: 'abc'$" -- \
      "$bin" repeat --map "$tmp/repeat_bad_meta.db" --sequence "$k" --every 2 --offset 1 --output "$tmp/r2.csv" --no-progress
fi
