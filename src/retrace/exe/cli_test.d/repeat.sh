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
  # Given the camera's height: the metric path's columns (the recent frames combined, then each frame's own) and,
  # with --overlay, the offset against ground truth drawn per frame.
  expect repeat-lateral-plot 0 "^lateral_m frame_lateral_m,frame_lateral_sigma_m lateral_vs_truth.png$" -- \
    bash -c "'$bin' repeat --map '$tmp/repeat_route.db' --sequence '$k' --every 2 --offset 1 --start-arc 0 \
      --camera-height 1.65 --output '$tmp/repeat_metric.csv' --overlay '$tmp/repeat_overlay' --evaluate \
      --no-progress >/dev/null && echo \$(head -1 '$tmp/repeat_metric.csv' | cut -d, -f33) \
      \$(head -1 '$tmp/repeat_metric.csv' | cut -d, -f39-40) \$(ls '$tmp/repeat_overlay' | grep lateral)"
  # --lateral-window 0: lateral_m is each frame's own (equal to frame_lateral_m, σ too, in every metric row).
  expect repeat-lateral-window-zero 0 "^0 [1-9][0-9]*$" -- \
    bash -c "'$bin' repeat --map '$tmp/repeat_route.db' --sequence '$k' --every 2 --offset 1 --start-arc 0 \
      --camera-height 1.65 --lateral-window 0 --output '$tmp/repeat_own.csv' --no-progress >/dev/null && \
      awk -F, 'NR > 1 && \$33 != \"\" { rows++; if (\$33 != \$39 || \$34 != \$40) differ++ } END { print differ + 0, rows + 0 }' \
      '$tmp/repeat_own.csv'"
  # A window shorter than a frame's travel holds one frame: lateral_m is then each frame's own value in every row
  # (the option reaches the localizer's window; its σ is the floored one, LocalizerOptions::lateral_noise_floor_px).
  expect repeat-lateral-window-short 0 "^0 [1-9][0-9]*$" -- \
    bash -c "'$bin' repeat --map '$tmp/repeat_route.db' --sequence '$k' --every 2 --offset 1 --start-arc 0 \
      --camera-height 1.65 --lateral-window 0.01 --output '$tmp/repeat_short.csv' --no-progress >/dev/null && \
      awk -F, 'NR > 1 && \$33 != \"\" { rows++; if (\$33 != \$39) differ++ } END { print differ + 0, rows + 0 }' \
      '$tmp/repeat_short.csv'"
  # --travel-window 0 (the heading's reference from the chords alone, as before the travel model) reaches the taught
  # path: the heading error changes in some metric rows, the lateral offset in none. Prints: rows with a heading that
  # differs, rows with a lateral_m that differs, metric rows.
  expect repeat-travel-window 0 "^[1-9][0-9]* 0 [1-9][0-9]*$" -- \
    bash -c "'$bin' repeat --map '$tmp/repeat_route.db' --sequence '$k' --every 2 --offset 1 --start-arc 0 \
      --camera-height 1.65 --travel-window 0 --output '$tmp/repeat_chords.csv' --no-progress >/dev/null && \
      paste -d, <(cut -d, -f33,35 '$tmp/repeat_metric.csv') <(cut -d, -f33,35 '$tmp/repeat_chords.csv') | \
      awk -F, 'NR > 1 && \$1 != \"\" { rows++; if (\$2 != \$4) heading++; if (\$1 != \$3) lateral++ } \
      END { print heading + 0, lateral + 0, rows + 0 }'"
  # --no-verified-placement: kitti07's odd frames never need a relocalization's resected placement (every frame is
  # tracked), so the states and arcs are those of the default frame for frame. Prints: rows that differ, rows.
  expect repeat-no-verified-placement 0 "^0 80$" -- \
    bash -c "'$bin' repeat --map '$tmp/repeat_route.db' --sequence '$k' --every 2 --offset 1 --start-arc 0 \
      --no-verified-placement --output '$tmp/repeat_unplaced.csv' --no-progress >/dev/null && \
      paste -d, <(cut -d, -f4,5 '$tmp/repeat_run.csv') <(cut -d, -f4,5 '$tmp/repeat_unplaced.csv') | \
      awk -F, 'NR > 1 { rows++; if (\$1 != \$3 || \$2 != \$4) differ++ } END { print differ + 0, rows + 0 }'"
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
  # The route's length is for information only (repeat does not read it): inspect shows a damaged one, as repeat
  # uses the map (map_fuzz_test found inspect refusing such a map while repeat used it).
  cp "$tmp/repeat_route.db" "$tmp/repeat_bad_length.db"
  sqlite3 "$tmp/repeat_bad_length.db" "UPDATE metadata SET value = 'abc' WHERE key = 'route_length_m'" 2>/dev/null &&
    expect inspect-bad-route-length 0 "route +length unreadable: 'abc'" -- "$bin" inspect --map "$tmp/repeat_bad_length.db"
fi

if [[ -d $data/kitti07 && -f $tmp/repeat_route.db ]]; then
  # Issue 16: a map written before key-images stored their relocalization signatures (schema 3) still localizes,
  # with a note that they were computed; every odd frame correct from the first, without a start arc.
  cp "$tmp/repeat_route.db" "$tmp/repeat_schema3.db"
  # The features and points go back to a row each (schema < 6; the blob layout of map/feature_blobs.h).
  python3 -c '
import sqlite3, struct, sys
def entries(blob, floats):
    i, previous = 0, -1
    while i < len(blob):
        value = shift = 0
        while True:
            byte = blob[i]; i += 1
            value |= (byte & 0x7F) << shift; shift += 7
            if byte < 0x80: break
        previous = value if previous < 0 else previous + value
        coordinates = struct.unpack_from("<%df" % floats, blob, i); i += 4 * floats
        if floats == 2:
            assert blob[i] == 0; i += 1  # no patch
        yield (previous,) + coordinates
c = sqlite3.connect(sys.argv[1])
for node, blob in c.execute("SELECT node_id, features FROM node_features").fetchall():
    c.executemany("INSERT INTO observations VALUES (?, ?, ?, ?, 0, NULL)", [(node,) + e for e in entries(blob, 2)])
for arc, blob in c.execute("SELECT arc_id, points FROM arc_point_lists").fetchall():
    c.executemany("INSERT INTO arc_points VALUES (?, ?, ?, ?, ?)", [(arc,) + e for e in entries(blob, 3)])
c.executescript("DROP TABLE node_features; DROP TABLE arc_point_lists; DROP TABLE signatures; PRAGMA user_version=3;")
c.close()' "$tmp/repeat_schema3.db" &&
    expect repeat-old-map-signatures-computed 0 "have no stored relocalization signature.*teach the map again" -- \
      "$bin" repeat --map "$tmp/repeat_schema3.db" --sequence "$k" --every 2 --offset 1 --output "$tmp/r3.csv" \
      --evaluate --no-progress &&
    expect repeat-old-map-correct 0 "80 frames: 100\.0% correct, 0 wrong" -- \
      "$bin" repeat --map "$tmp/repeat_schema3.db" --sequence "$k" --every 2 --offset 1 --output "$tmp/r3.csv" \
      --evaluate --no-progress
  # Kidnapped starts (retrace bench kidnap): fresh localizers at random frames, scored against KITTI's poses.
  expect bench-kidnap-kitti 0 "kidnap: 10 starts on a map of [0-9]+ key-images .* 0 wrong frames in 0 starts" -- \
    "$bin" bench kidnap --map "$tmp/repeat_route.db" --sequence "$k" --starts 10 --frames 2
  expect bench-retrieval-kitti 0 "retrieval \(quantised index\): [0-9]+ frames, [0-9]+ key-images: recall@1" -- \
    "$bin" bench retrieval --map "$tmp/repeat_route.db" --sequence "$k"
  expect inspect-signature-bytes 0 "kB of relocalization signatures" -- "$bin" inspect --map "$tmp/repeat_route.db"
fi
