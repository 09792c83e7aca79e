# retrace teach and retrace inspect.
if [[ -d $data/kitti07 ]]; then
  expect teach-kitti 0 'key-images' -- "$bin" teach --sequence "$data/kitti07" --map "$tmp/k07.db" --every 2 --no-progress
  expect inspect-summary 0 'key-images' -- "$bin" inspect --map "$tmp/k07.db"
  # --json: one object with the documented fields; arcs chain the nodes.
  expect inspect-json 0 'ok' -- bash -c "'$bin' inspect --map '$tmp/k07.db' --json | python3 -c '
import json, sys
m = json.load(sys.stdin)
assert len(m[\"nodes\"]) >= 2 and len(m[\"arcs\"]) == len(m[\"nodes\"]) - 1
for n in m[\"nodes\"]:
    assert n[\"image\"].endswith(\".png\") and n[\"source_frame\"] % 2 == 0
for a in m[\"arcs\"]:
    assert len(a[\"R\"]) == 9 and len(a[\"t\"]) == 3 and a[\"features\"] >= 50 and a[\"sigma_p\"] >= 0
    assert abs(sum(x * x for x in a[\"t\"]) - 1) < 1e-6
print(\"ok\")'"
  expect inspect-report 0 'key_image_poses.png' -- "$bin" inspect --map "$tmp/k07.db" --report "$tmp/report" \
    --ground-truth "$data/kitti07/poses.txt"
  # Given the camera's height, teach fits the metric path's ground once and stores it; inspect summarises the fits.
  expect teach-camera-height 0 "metric path: the ground's normal and every arc's ground plane stored" -- \
    "$bin" teach --sequence "$data/kitti07" --map "$tmp/k07h.db" --every 2 --no-progress --camera-height 1.65
  expect inspect-ground-fits 0 'ground_fits +[0-9]+ arcs, [0-9]+ with a ground plane' -- \
    "$bin" inspect --map "$tmp/k07h.db"
  # ... and reports the rig the arcs show (repeat/taught_path.h, TravelModel): a car's camera travels as if 0.5-2.5 m
  # ahead of the rear axle it turns about (kitti07: 0.88 m).
  expect teach-vehicle 0 "^vehicle: the camera travels as if (0\.[5-9]|1\.[0-9]|2\.[0-4])[0-9] m ahead of the point" -- \
    "$bin" teach --sequence "$data/kitti07" --map "$tmp/k07v.db" --every 2 --no-progress --camera-height 1.65
  # An existing map is never replaced without --overwrite, and stays intact.
  before=$(md5sum "$tmp/k07.db")
  expect teach-no-overwrite 1 'exists already' -- "$bin" teach --sequence "$data/kitti07" --map "$tmp/k07.db"
  expect teach-map-intact 0 '' -- bash -c "[[ '$before' == \"\$(md5sum '$tmp/k07.db')\" ]]"
  # A camera that stands still (kitti07's first frame eight times) gives no arc: a one-line error naming the
  # sequence, exit 1, and no map repeat would refuse.
  mkdir -p "$tmp/still/image_0"
  cp "$data/kitti07/calib.txt" "$tmp/still/"
  for i in 0 1 2 3 4 5 6 7; do
    cp "$data/kitti07/image_0/000000.png" "$tmp/still/image_0/00000$i.png"
    echo "0.$i" >>"$tmp/still/times.txt"
  done
  expect teach-still-camera 1 \
    "^retrace: error: $tmp/still: teach made no arc from its 8 frames: the camera did not move" -- \
    "$bin" teach --sequence "$tmp/still" --map "$tmp/still.db" --no-progress
  expect teach-still-no-map 0 '' -- bash -c "[[ ! -e '$tmp/still.db' ]]"
  # Frames too small to track (kitti07 at 97x29 px) give no arc either, and the error says why, not "did not move".
  expect teach-too-small 1 "teach made no arc from its 80 frames: [0-9]+ times no frame could be tracked .*97x29 px" \
    -- "$bin" teach --sequence "$data/kitti07" --map "$tmp/tiny.db" --width 97 --every 2 --no-progress
  # At 160x48 px most frames cannot be tracked either: the map is written, in more pieces than arcs, and teach warns.
  expect teach-in-pieces 0 "teach: the map is broken [0-9]+ times and has [0-9]+ arcs: repeat will be .*160x48 px" \
    -- "$bin" teach --sequence "$data/kitti07" --map "$tmp/pieces.db" --width 160 --every 2 --no-progress
fi
expect teach-missing-sequence 1 'retrace: error: .*nowhere' -- "$bin" teach --sequence "$tmp/nowhere" --map "$tmp/x.db"
echo "not a map" >"$tmp/foreign.db"
expect inspect-foreign 1 "retrace: error: $tmp/foreign.db: not a retrace map" -- "$bin" inspect --map "$tmp/foreign.db"
expect inspect-missing 1 'no such map file' -- "$bin" inspect --map "$tmp/missing.db"
