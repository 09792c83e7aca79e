# retrace calibrate: one-line errors for bad arguments and folders; a real calibration when the data is present.
mkdir -p "$tmp/calib_empty"
expect calibrate-bad-board 1 "^retrace: error: invalid --board '9by6'" -- \
  "$bin" calibrate --images "$tmp/calib_empty" --board 9by6 --out "$tmp/cam.yaml"
expect calibrate-bad-model 1 "^retrace: error: invalid --model 'fisheye'" -- \
  "$bin" calibrate --images "$tmp/calib_empty" --model fisheye --out "$tmp/cam.yaml"
expect calibrate-missing-dir 1 "^retrace: error: .*calib_missing: folder not found$" -- \
  "$bin" calibrate --images "$tmp/calib_missing" --board 9x6 --out "$tmp/cam.yaml"
expect calibrate-no-images 1 "^retrace: error: .*calib_empty: no image files" -- \
  "$bin" calibrate --images "$tmp/calib_empty" --board 9x6 --out "$tmp/cam.yaml"
echo "not an image" >"$tmp/calib_empty/junk.png"
expect calibrate-unreadable-images 1 "calib_empty: only 0 of 1 images show the 9x6 chessboard" -- \
  "$bin" calibrate --images "$tmp/calib_empty" --board 9x6 --out "$tmp/cam.yaml"

if [[ -d $data/chessboard_640x480/left ]]; then
  expect calibrate-real 0 "RMS reprojection error: 0\.[0-4][0-9]* px over 13 of 13 images" -- \
    "$bin" calibrate --images "$data/chessboard_640x480/left" --board 9x6 --square 0.025 --out "$tmp/left.yaml"
  expect calibrate-real-per-image 0 "left14\.jpg +used +rms 0\.[0-9]+ px" -- \
    "$bin" calibrate --images "$data/chessboard_640x480/left" --board 9x6 --square 0.025 --out "$tmp/left.yaml"
  # The written file is ROS camera_info and reads back with the calibrated focal length (OpenCV: 535.9).
  expect calibrate-real-keys 0 "distortion_model: plumb_bob" -- cat "$tmp/left.yaml"
  expect calibrate-real-readback 0 "fx=53[0-9]\.[0-9]+ fy=53[0-9]\.[0-9]+ cx=34[0-9]\.[0-9]+ cy=23[0-9]\." -- \
    "$bin" camera-info --camera "$tmp/left.yaml"
fi
