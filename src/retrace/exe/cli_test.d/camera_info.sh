# retrace camera-info: reads every supported calibration format; bad files give a one-line error and exit 1.
printf '%s\n' '- 1' '- 2' >"$tmp/list.yaml"
expect camera-info-list 1 "^retrace: error: .*list\.yaml: not a camera calibration file" -- \
  "$bin" camera-info --camera "$tmp/list.yaml"
head -c 2000 /dev/urandom >"$tmp/junk.yaml"
expect camera-info-junk 1 "^retrace: error: .*junk\.yaml: " -- "$bin" camera-info --camera "$tmp/junk.yaml"
# Exactly one line on stderr for a bad file.
if [[ $("$bin" camera-info --camera "$tmp/junk.yaml" 2>&1 >/dev/null | wc -l) -eq 1 ]]; then
  passed=$((passed + 1))
else
  echo "FAIL camera-info-junk-one-line"
  failures=$((failures + 1))
fi
expect camera-info-missing 1 "^retrace: error: .*nothing\.yaml: file not found$" -- \
  "$bin" camera-info --camera "$tmp/nothing.yaml"
printf 'image_width: 640\nimage_height: 480\ncamera_matrix: [0, 0, 320, 0, 500, 240, 0, 0, 1]\n' >"$tmp/f0.yaml"
expect camera-info-focal 1 "f0\.yaml: non-positive focal length" -- "$bin" camera-info --camera "$tmp/f0.yaml"
expect camera-info-bad-size 1 "invalid --image-size '640'" -- \
  "$bin" camera-info --camera "$tmp/f0.yaml" --image-size 640
printf 'image_width: 640\nimage_height: 480\ncamera_matrix: [500, 0, 320, 0, 500, 240, 0, 0, 1]\n' >"$tmp/ok.yaml"
expect camera-info-pinhole 0 "field of view: horizontal 65\.[0-9]+ deg" -- "$bin" camera-info --camera "$tmp/ok.yaml"
expect camera-info-size-mismatch 1 "image size mismatch: file says 640x480, images are 752x480" -- \
  "$bin" camera-info --camera "$tmp/ok.yaml" --image-size 752x480

if [[ -d $data/kitti07 ]]; then
  expect camera-info-kitti-no-size 1 "calib\.txt: the file has no image size" -- \
    "$bin" camera-info --camera "$data/kitti07/calib.txt"
  expect camera-info-kitti 0 "fx=707\.0912 fy=707\.0912 cx=601\.8873 cy=183\.1104" -- \
    "$bin" camera-info --camera "$data/kitti07/calib.txt" --image-size 1226x370
fi
if [[ -d $data/euroc_v101_clip ]]; then
  expect camera-info-euroc 0 "round-trip error .*: max [0-9.e-]+ px" -- \
    "$bin" camera-info --camera "$data/euroc_v101_clip/mav0/cam0/sensor.yaml"
fi
