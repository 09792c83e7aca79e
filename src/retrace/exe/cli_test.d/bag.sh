# ROS bags as sequences (--sequence FILE.bag, --topic, --camera-topic) and `sim render --bag`: a tiny simulated bag
# through sequence-info, teach and repeat, and the one-line errors of bad bags. A retrace built without ROS says so.
if "$bin" sim render --bag "$tmp/drive.bag" --frames 12 --width 160 --height 120 --quiet >"$tmp/bag_render.txt" 2>&1
then
  expect bag-info 0 'layout: +rosbag' -- "$bin" sequence-info "$tmp/drive.bag"
  expect bag-info-frames 0 'frames: +12 listed, 12 readable' -- "$bin" sequence-info "$tmp/drive.bag"
  expect bag-info-camera 0 'calibration: +CameraInfo, perspective' -- "$bin" sequence-info "$tmp/drive.bag"
  expect bag-teach 0 'from 12 frames' -- "$bin" teach --sequence "$tmp/drive.bag" --topic /camera/image_raw \
    --map "$tmp/bag_map.db" --no-progress
  expect bag-repeat 0 'repeat: 12 frames' -- "$bin" repeat --map "$tmp/bag_map.db" --sequence "$tmp/drive.bag" \
    --output "$tmp/bag_repeat.csv" --no-progress
  expect bag-missing-topic 1 "^retrace: error: $tmp/drive.bag: no topic /camera/image in the bag \(image topics: /camera/image_raw\)$" -- \
    "$bin" teach --sequence "$tmp/drive.bag" --topic /camera/image --map "$tmp/bag_bad.db"
  expect bag-wrong-type 1 "^retrace: error: $tmp/drive.bag: topic /ground_truth/pose carries geometry_msgs/PoseStamped, not sensor_msgs/Image or sensor_msgs/CompressedImage$" -- \
    "$bin" repeat --map "$tmp/bag_map.db" --sequence "$tmp/drive.bag" --topic /ground_truth/pose --output "$tmp/x.csv"
  expect bag-camera-topic 1 "^retrace: error: $tmp/drive.bag: topic /camera/image_raw carries sensor_msgs/Image, not sensor_msgs/CameraInfo$" -- \
    "$bin" teach --sequence "$tmp/drive.bag" --camera-topic /camera/image_raw --map "$tmp/bag_bad.db"
  printf 'not a bag\n' >"$tmp/text.bag"
  expect bag-not-a-bag 1 "^retrace: error: $tmp/text.bag: not a readable ROS bag \(" -- \
    "$bin" repeat --map "$tmp/bag_map.db" --sequence "$tmp/text.bag" --output "$tmp/x.csv"
  expect bag-missing 1 "^retrace: error: $tmp/none.bag: no such file$" -- \
    "$bin" teach --sequence "$tmp/none.bag" --map "$tmp/bag_bad.db"
  expect bag-topic-not-bag 1 "--topic and --camera-topic are for ROS bags" -- \
    "$bin" teach --sequence "$tmp" --topic /camera/image_raw --map "$tmp/bag_bad.db"
  expect bag-contact-sheet 1 "^retrace: error: sim render: --contact-sheet is written with --out only$" -- \
    "$bin" sim render --bag "$tmp/x.bag" --contact-sheet "$tmp/x.png" --frames 2 --quiet
else
  expect bag-without-ros 0 'built without ROS' -- cat "$tmp/bag_render.txt"
  printf 'not a bag\n' >"$tmp/text.bag"
  expect bag-without-ros-sequence 1 "^retrace: error: $tmp/text.bag: a ROS bag, but this retrace was built without ROS" -- \
    "$bin" sequence-info "$tmp/text.bag"
fi
expect sim-render-needs-output 1 '^retrace: error: sim render: give --out FOLDER or --bag FILE$' -- \
  "$bin" sim render --frames 2 --quiet
