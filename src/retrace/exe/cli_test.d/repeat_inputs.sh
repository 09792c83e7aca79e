# shellcheck shell=bash
# Inputs that do not fit: implausible calibrations, frames that change size, a repeat camera or frames other than the
# map's. Each is refused with one line naming the file and both values (sourced by cli_test.sh after repeat.sh).

# Implausible calibrations: a focal length of 1e20 px, the principal point far outside, a distortion of k1 = 50.
printf 'image_width: 640\nimage_height: 480\ncamera_matrix: [1e20, 0, 320, 0, 1e20, 240, 0, 0, 1]\n' >"$tmp/narrow.yaml"
expect camera-implausible-focal 1 "^retrace: error: .*narrow\.yaml: implausible calibration: field of view 0\.00° x 0\.00°" -- \
  "$bin" camera-info --camera "$tmp/narrow.yaml"
printf 'image_width: 640\nimage_height: 480\ncamera_matrix: [500, 0, -5000, 0, 500, 240, 0, 0, 1]\n' >"$tmp/cx.yaml"
expect camera-implausible-centre 1 "cx\.yaml: implausible calibration: principal point \(-5000\.0, 240\.0\) lies outside the 640x480 image" -- \
  "$bin" camera-info --camera "$tmp/cx.yaml"
printf 'image_width: 640\nimage_height: 480\ncamera_matrix: [500, 0, 320, 0, 500, 240, 0, 0, 1]\ndistortion_coefficients: [50, 0, 0, 0, 0]\n' \
  >"$tmp/k1.yaml"
expect camera-implausible-distortion 1 "k1\.yaml: implausible calibration: the lens distortion magnifies" -- \
  "$bin" camera-info --camera "$tmp/k1.yaml"

# Frames of two sizes in one sequence: refused at the first odd frame, naming it and both sizes.
"$bin" sim render --out "$tmp/sizes_a" --frames 3 --width 96 --height 72 --quiet >/dev/null 2>&1
"$bin" sim render --out "$tmp/sizes_b" --frames 1 --width 80 --height 60 --quiet >/dev/null 2>&1
mkdir -p "$tmp/mixed"
cp "$tmp/sizes_a/image_0/000000.png" "$tmp/mixed/a0.png"
cp "$tmp/sizes_a/image_0/000001.png" "$tmp/mixed/a1.png"
cp "$tmp/sizes_b/image_0/000000.png" "$tmp/mixed/a2.png"
cp "$tmp/sizes_a/image_0/000002.png" "$tmp/mixed/a3.png"
expect sequence-mixed-sizes 1 "^retrace: error: .*mixed/a2\.png: image is 80x60 but the sequence's first frame is 96x72" -- \
  "$bin" teach --sequence "$tmp/mixed" --camera "$tmp/sizes_a/calib.txt" --map "$tmp/mixed.db" --no-progress

if [[ -d $data/kitti07 && -f $tmp/repeat_route.db ]]; then
  k=$data/kitti07
  # A repeat camera other than the map's (focal length 500 instead of 707 px) is refused with both values.
  sed 's/7\.070912000000e+02/5.000000000000e+02/g' "$k/calib.txt" >"$tmp/calib500.txt"
  expect repeat-other-camera 1 "^retrace: error: .*calib500\.txt: differs from the map's camera \(.* px apart .*fx 500 .*the map's perspective fx 707\.091" -- \
    "$bin" repeat --map "$tmp/repeat_route.db" --sequence "$k" --camera "$tmp/calib500.txt" --output "$tmp/r3.csv" --no-progress
  # The same calibration given explicitly is the map's camera.
  expect repeat-same-camera 0 '^repeat: 4 frames' -- \
    "$bin" repeat --map "$tmp/repeat_route.db" --sequence "$k" --camera "$k/calib.txt" --every 40 --start-arc 0 \
    --output "$tmp/r4.csv" --no-progress
  # Frames of another shape than the map's key-images (a simulated 96x72 drive on the KITTI map).
  expect repeat-other-frames 1 "^retrace: error: .*sizes_a: frames are 96x72 \(1226x920 at the map's width\) but the map's camera images 1226x370" -- \
    "$bin" repeat --map "$tmp/repeat_route.db" --sequence "$tmp/sizes_a" --output "$tmp/r5.csv" --no-progress
  # An implausible calibration never starts a teach (fx = 1e308 used to run 17 s for a map without arcs).
  sed 's/7\.070912000000e+02/1e308/g' "$k/calib.txt" >"$tmp/calib_inf.txt"
  expect teach-implausible-camera 1 "calib_inf\.txt: implausible calibration: field of view 0\.00°" -- \
    "$bin" teach --sequence "$k" --camera "$tmp/calib_inf.txt" --map "$tmp/inf.db" --no-progress
  expect teach-implausible-no-map 0 '' -- bash -c "[[ ! -e '$tmp/inf.db' ]]"
fi
