# retrace sim: the simulator's bounds (issues 18 and 19). A drive asked for more frames than its route has stops at
# the route's end and says how many frames it wrote; every number a scenario file or an option sets has a range,
# refused with one line naming the file (or option), the key and the range, exit code 1.
expect sim-route-end 0 'the route ends after ([0-9]+) frames: [0-9]+ fewer than the 100000 asked for' -- \
  "$bin" sim render --out "$tmp/route_end" --frames 100000 --width 16 --height 12 --segments 1 --pedestrians 0 --quiet
expect sim-route-end-files 0 '^([0-9]+) \1$' -- bash -c "echo \$(ls '$tmp/route_end/image_0' | wc -l) \
  \$(wc -l <'$tmp/route_end/poses.txt')"
expect sim-route-end-whole 0 "^wrote $(ls "$tmp/route_end/image_0" 2>/dev/null | wc -l) frames" -- \
  "$bin" sim render --out "$tmp/route_whole" --frames 0 --width 16 --height 12 --segments 1 --pedestrians 0 --quiet
# Options: the same check as the file's keys, the option named.
expect sim-bad-frames 1 '^retrace: error: --frames: must be in 0\.\.1000000, got -1$' -- \
  "$bin" sim render --out "$tmp/bad" --frames -1
expect sim-bad-threads 1 '^retrace: error: --threads: must be in 1\.\.256, got 100000$' -- \
  "$bin" sim render --out "$tmp/bad" --threads 100000
expect sim-bad-threads-zero 1 '^retrace: error: --threads: must be in 1\.\.256, got 0$' -- \
  "$bin" sim render --out "$tmp/bad" --threads 0
expect sim-bad-pedestrians 1 '^retrace: error: --pedestrians: must be in 0\.\.1000, got 100000000$' -- \
  "$bin" sim render --out "$tmp/bad" --pedestrians 100000000
expect sim-bad-segments 1 '^retrace: error: --segments: must be in 1\.\.1000, got 100000000$' -- \
  "$bin" sim render --out "$tmp/bad" --segments 100000000
expect sim-bad-size 1 "^retrace: error: --width: 8192 x 8192 pixels at render.antialiasing 2 exceed the renderer's" -- \
  "$bin" sim render --out "$tmp/bad" --width 8192 --height 8192
expect sim-bad-seed 1 '^retrace: error: --seed: must be in 0\.\.9223372036854775807, got -1$' -- \
  "$bin" sim render --out "$tmp/bad" --seed -1
expect sim-bad-sheet-every 1 '^retrace: error: --contact-sheet-every: must be in 1\.\.1000000, got 0$' -- \
  "$bin" sim render --out "$tmp/bad" --contact-sheet "$tmp/s.png" --contact-sheet-every 0
expect sim-drive-bad-width 1 '^retrace: error: --width: must be in 8\.\.8192 pixels, got 0$' -- \
  "$bin" sim drive --map "$tmp/none.db" --out "$tmp/drive" --width 0
expect sim-drive-bad-max-frames 1 '^retrace: error: sim drive options: max_frames must be in 1\.\.1000000, got 0$' -- \
  "$bin" sim drive --map "$tmp/none.db" --out "$tmp/drive" --max-frames 0
# Scenario files: file, line, key, range and value; boundary values accepted.
printf 'frames: -5\n' >"$tmp/frames.yaml"
expect sim-file-bad-frames 1 '^retrace: error: .*frames.yaml: line 1: frames: must be in 0\.\.1000000, got -5$' -- \
  "$bin" sim render --scenario "$tmp/frames.yaml" --out "$tmp/bad"
printf 'town:\n  pedestrians: 100000000\n' >"$tmp/crowd.yaml"
expect sim-file-bad-pedestrians 1 \
  '^retrace: error: .*crowd.yaml: line 2: town.pedestrians: must be in 0\.\.1000, got 100000000$' -- \
  "$bin" sim render --scenario "$tmp/crowd.yaml" --out "$tmp/bad"
printf 'route:\n  segments: 100000000\n' >"$tmp/long.yaml"
expect sim-file-bad-segments 1 \
  '^retrace: error: .*long.yaml: line 2: route.segments: must be in 1\.\.1000, got 100000000$' -- \
  "$bin" sim render --scenario "$tmp/long.yaml" --out "$tmp/bad"
printf 'seed: 1\nrender:\n  threads: 100000\n' >"$tmp/threads.yaml"
expect sim-file-bad-threads 1 \
  '^retrace: error: .*threads.yaml: line 3: render.threads: must be in 1\.\.256, got 100000$' -- \
  "$bin" sim render --scenario "$tmp/threads.yaml" --out "$tmp/bad"
printf 'render:\n  threads: 256\n  antialiasing: 8\ntown:\n  pedestrians: 1000\n' >"$tmp/bounds.yaml"
expect sim-file-bounds 0 'wrote 1 frames' -- \
  "$bin" sim render --scenario "$tmp/bounds.yaml" --out "$tmp/bounds" --frames 1 --width 16 --height 12 --quiet
