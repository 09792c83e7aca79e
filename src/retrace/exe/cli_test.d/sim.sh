# retrace sim: example scenario, a tiny render (KITTI layout), the repeat variant, bad scenario files.
expect sim-example 0 'sun_azimuth_deg' -- "$bin" sim example-scenario
"$bin" sim example-scenario >"$tmp/town.yaml"
expect sim-render 0 'wrote 4 frames' -- "$bin" sim render --scenario "$tmp/town.yaml" --out "$tmp/teach" --frames 4 \
  --width 80 --height 60 --quiet --contact-sheet "$tmp/sheet.png" --contact-sheet-every 2
expect sim-render-layout 0 '^4 4 4$' -- bash -c "echo \$(ls '$tmp/teach/image_0' | wc -l) \$(wc -l <'$tmp/teach/poses.txt') \$(wc -l <'$tmp/teach/times.txt')"
expect sim-render-calib 0 '^P0: ' -- head -1 "$tmp/teach/calib.txt"
expect sim-contact-sheet 0 'sheet.png' -- ls "$tmp/sheet.png"
expect sim-repeat 0 'repeat variant' -- "$bin" sim render --out "$tmp/repeat" --variant repeat --frames 2 --width 80 \
  --height 60 --quiet
printf 'seed: 1\ncamera:\n  model: perspective\n  width: wide\n' >"$tmp/bad.yaml"
expect sim-bad-value 1 'bad.yaml: line 4: camera.width: expected an integer' -- \
  "$bin" sim render --scenario "$tmp/bad.yaml" --out "$tmp/bad"
printf 'seed: 1\nrout:\n  type: auto\n' >"$tmp/bad2.yaml"
expect sim-unknown-key 1 'bad2.yaml: line 2: rout: unknown key' -- \
  "$bin" sim render --scenario "$tmp/bad2.yaml" --out "$tmp/bad"
expect sim-missing-file 1 'cannot open the scenario file' -- \
  "$bin" sim render --scenario "$tmp/none.yaml" --out "$tmp/bad"
expect sim-bad-variant 105 'variant' -- "$bin" sim render --out "$tmp/bad" --variant sideways
# Overrides of the drive: a crossing route at 12 m/s, 5 Hz, 70 pedestrians, dusk repeat 2.5 m to the side; bad values.
expect sim-overrides 0 'wrote 2 frames .* repeat variant' -- "$bin" sim render --out "$tmp/crossing" --variant repeat \
  --frames 2 --width 80 --height 60 --route crossing --speed 12 --frame-rate 5 --pedestrians 70 --lighting noon \
  --repeat-lighting dusk --lateral-offset 2.5 --quiet
expect sim-bad-speed 1 '^retrace: error: --speed: must be in \[0.5, 50\] m/s, got 0$' -- \
  "$bin" sim render --out "$tmp/bad" --speed 0
expect sim-bad-lighting 1 "^retrace: error: --lighting: unknown lighting 'sunset' \(noon, low-sun, dusk or " -- \
  "$bin" sim render --out "$tmp/bad" --lighting sunset
expect sim-bad-route 1 "^retrace: error: --route: unknown route 'spiral'" -- \
  "$bin" sim render --out "$tmp/bad" --route spiral
# sim drive (closed loop): bad options, a missing map, a map whose key-images do not fit the scenario's camera.
expect sim-drive-bad-speed 1 '^retrace: error: sim drive options: tracking: max_speed must be in \(0, 50\] m/s, got 0$' -- \
  "$bin" sim drive --map "$tmp/none.db" --out "$tmp/drive" --speed 0
expect sim-drive-missing-map 1 '^retrace: error: .*none.db' -- "$bin" sim drive --map "$tmp/none.db" --out "$tmp/drive"
# The scenario options of sim render, checked the same way (before the map is opened).
expect sim-drive-bad-frame-rate 1 '^retrace: error: --frame-rate: must be in \[0.1, 1000\] Hz, got 0$' -- \
  "$bin" sim drive --map "$tmp/none.db" --out "$tmp/drive" --frame-rate 0
expect sim-drive-bad-route 1 "^retrace: error: --route: unknown route 'spiral'" -- \
  "$bin" sim drive --map "$tmp/none.db" --out "$tmp/drive" --route spiral
if [[ -f $tmp/repeat_route.db ]]; then
  expect sim-drive-camera-mismatch 1 "repeat_route.db: key-images are 1226x370 but the scenario's camera is 320x240" -- \
    "$bin" sim drive --map "$tmp/repeat_route.db" --out "$tmp/drive" --width 320 --height 240 --quiet
fi
# A short closed loop in the default town (taught with the car's camera height): drive.csv holds, per frame, the
# offset the path law steered by next to each frame's own and the truth, and lateral.png plots them.
"$bin" sim render --out "$tmp/loop_teach" --frames 60 --width 320 --height 240 --quiet >/dev/null
"$bin" teach --sequence "$tmp/loop_teach" --map "$tmp/loop.db" --camera-height 1.5 --no-progress >/dev/null
expect sim-drive-offsets 0 'lateral\.png' -- "$bin" sim drive --map "$tmp/loop.db" --out "$tmp/loop" --width 320 \
  --height 240 --taught-poses "$tmp/loop_teach/poses.txt" --max-frames 40 --quiet
# Every frame steered by the metric path, the offset it steered by within 0.1 m of the truth (0.03 m measured).
expect sim-drive-steered-offset 0 '^40 40 40$' -- awk -F, 'NR == 1 { for (i = 1; i <= NF; ++i) c[$i] = i; next }
  { path += $c["mode"] == "path"; steered += $c["steered_lateral_m"] != "" && $c["steered_heading_error_rad"] != ""
    e = $c["steered_lateral_m"] - $c["true_lateral_m"]; near += e < 0.1 && e > -0.1 }
  END { print path, steered, near }' "$tmp/loop/drive.csv"
expect sim-drive-lateral-plot 0 'lateral\.png' -- ls "$tmp/loop/lateral.png"
