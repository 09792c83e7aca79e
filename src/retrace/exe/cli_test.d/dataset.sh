# shellcheck shell=bash
# CLI checks of `retrace sequence-info` and `retrace perturb` (sourced by cli_test.sh: $bin, $data, $tmp, expect).

expect sequence-info-missing 1 "^retrace: error: $tmp/no_such_sequence: no such file or folder$" -- \
  "$bin" sequence-info "$tmp/no_such_sequence"
mkdir -p "$tmp/empty_folder"
expect sequence-info-empty 1 "^retrace: error: .*empty_folder: no images" -- "$bin" sequence-info "$tmp/empty_folder"
expect perturb-missing 1 "^retrace: error: $tmp/no_such_sequence: no such file or folder$" -- \
  "$bin" perturb --sequence "$tmp/no_such_sequence" --out "$tmp/never"
expect perturb-needs-out 106 "--out is required" -- "$bin" perturb --sequence "$tmp/empty_folder"

if [[ -d $data/kitti07 ]]; then
  expect sequence-info-kitti 0 'frames: +160 listed, 160 readable' -- \
    bash -o pipefail -c "'$bin' sequence-info '$data/kitti07' | tee '$tmp/kitti07_info.txt'"
  expect sequence-info-kitti-size 0 'image size: +1226x370' -- cat "$tmp/kitti07_info.txt"
  expect sequence-info-kitti-calib 0 'calibration: +.*kitti07/calib.txt' -- cat "$tmp/kitti07_info.txt"
  expect sequence-info-kitti-gt 0 'trajectory: +90\.6[0-9] m' -- "$bin" sequence-info "$data/kitti07/image_0"
  expect perturb-bad-range 1 "^retrace: error: --occluder-frames: '50:40': LAST is before FIRST$" -- \
    "$bin" perturb --sequence "$data/kitti07" --out "$tmp/p_bad" --occluder-fraction 0.4 --occluder-frames 50:40
  expect perturb-bad-gamma 1 "^retrace: error: invalid perturbation: gamma must be > 0$" -- \
    "$bin" perturb --sequence "$data/kitti07" --out "$tmp/p_bad" --gamma 0
  # Repeat pass of the standard pseudo-repeat: odd frames, darker, noisy, an occluder, every 4th odd frame dropped.
  expect perturb-kitti 0 'wrote 60 frames .*\(20 dropped, 0 unreadable in the source\) with ground-truth poses' -- \
    "$bin" perturb --sequence "$data/kitti07" --out "$tmp/p_odd" --every 2 --offset 1 --drop-every 4 \
    --brightness 0.6 --gamma 1.4 --noise 6 --occluder-fraction 0.4 --occluder-frames 40:50 --seed 3
  expect perturb-kitti-readback 0 'frames: +60 listed, 60 readable' -- \
    bash -o pipefail -c "'$bin' sequence-info '$tmp/p_odd' | tee '$tmp/p_odd_info.txt'"
  expect perturb-kitti-poses 0 'ground truth: .*poses.txt \(60 camera poses\)' -- cat "$tmp/p_odd_info.txt"
  # Output frames 0..3 are source frames 1, 3, 5, (7 dropped) 9.
  expect perturb-kitti-source-frames 0 '^1 3 5 9$' -- bash -c "head -4 '$tmp/p_odd/source_frames.txt' | paste -sd' '"
  # The pose of output frame 3 is the pose of source frame 9, byte for byte in value.
  expect perturb-kitti-pose-aligned 0 '^0\.0000(0|1)$' -- bash -c \
    "paste -d' ' <(sed -n 4p '$tmp/p_odd/poses.txt') <(sed -n 10p '$data/kitti07/poses.txt') | \
     awk '{m=0; for(i=1;i<=12;i++){d=\$i-\$(i+12); if(d<0)d=-d; if(d>m)m=d}; printf \"%.5f\n\", m}'"
  expect perturb-out-not-empty 1 "p_odd: exists and is not an empty folder" -- \
    "$bin" perturb --sequence "$data/kitti07" --out "$tmp/p_odd"
  # KITTI's colour download has image_2 and image_3 only: the left colour camera is read (in grey) with calib.txt's
  # P2. Its first 40 frames made colour (RGB PNGs) by Debian's Pillow, which python3-matplotlib brings.
  mkdir -p "$tmp/colour/image_2"
  /usr/bin/python3 -c "
from PIL import Image
for i in range(40):
    Image.open('$data/kitti07/image_0/%06d.png' % i).convert('RGB').save('$tmp/colour/image_2/%06d.png' % i)"
  head -40 "$data/kitti07/times.txt" >"$tmp/colour/times.txt"
  head -40 "$data/kitti07/poses.txt" >"$tmp/colour/poses.txt"
  cp "$data/kitti07/calib.txt" "$tmp/colour/"
  expect sequence-info-kitti-colour 0 "calibration: +$tmp/colour/calib.txt \(P2\)" -- "$bin" sequence-info "$tmp/colour"
  expect teach-kitti-colour 0 'key-images' -- "$bin" teach --sequence "$tmp/colour" --map "$tmp/colour.db" --no-progress
  # perturb writes image_0: the colour camera's calibration goes along as camera.yaml.
  expect perturb-kitti-colour 0 'calibration: +.*p_colour/camera.yaml' -- bash -o pipefail -c \
    "'$bin' perturb --sequence '$tmp/colour' --out '$tmp/p_colour' --every 2 >/dev/null && '$bin' sequence-info '$tmp/p_colour'"
fi

if [[ -d $data/euroc_v101_clip ]]; then
  expect sequence-info-euroc 0 'frames: +95 listed, 95 readable' -- "$bin" sequence-info "$data/euroc_v101_clip"
  expect sequence-info-euroc-cam1 0 'unreadable: +4' -- "$bin" sequence-info "$data/euroc_v101_clip/mav0/cam1"
fi
