#!/usr/bin/env bash
# retrace_node end to end: a roscore on a free localhost port (its ROS_HOME and logs in a temporary folder removed at
# the end), a simulated repeat drive played from a bag into two nodes, their topics recorded (node_test.py listen)
# and checked against `retrace repeat` on the same bag (node_test.py compare):
#  - node `every` (~process_every_frame): the same state (tracking, then lost or relocalizing past the map's end),
#    arc, nodes and confidence per frame as repeat's CSV, the
#    same steering (within 1e-4, the CSV's precision), cmd_vel = (speed, -steering) while tracking, (0, 0) otherwise;
#  - node `live` (the default: the newest frame only) fed at 50x the camera's rate (a frame every 2 ms, faster than a
#    relocalizing frame takes on any machine): it drops stale frames and still processes the bag's last frame;
#  - /diagnostics reports the node tracking.
# Usage: node_test.sh RETRACE_BINARY RETRACE_NODE_BINARY (empty when built without ROS). Exits 77 (ctest: skipped)
# when ROS or the node is absent.
set -u
retrace=$1
node=${2:-}
here=$(cd "$(dirname "$0")" && pwd)
frames=80  # repeated; the map is taught on the first 60 (the last 20 frames drive past its end: lost)
taught=60
speed=0.7

skip() {
  echo "SKIPPED: $*"
  exit 77
}
[[ -n $node && -x $node ]] || skip "retrace was built without ROS (no retrace_node; install the ROS packages of scripts/install-deps and build again)"
for tool in roscore rosbag; do
  command -v "$tool" >/dev/null || skip "$tool not found (Debian package ros-core, scripts/install-deps)"
done
/usr/bin/python3 -c 'import rospy, geometry_msgs.msg, diagnostic_msgs.msg, std_msgs.msg' 2>/dev/null ||
  skip "rospy or its message classes are missing (python3-rospy, python3-geometry-msgs, python3-diagnostic-msgs)"

tmp=$(mktemp -d)
pids=()
cleanup() {
  # Our own processes only, by id: SIGINT first (roscore then stops its master and rosout), SIGKILL after 10 s.
  local pid
  for pid in "${pids[@]}"; do kill -INT "$pid" 2>/dev/null; done
  for _ in $(seq 100); do
    local alive=0
    for pid in "${pids[@]}"; do kill -0 "$pid" 2>/dev/null && alive=1; done
    ((alive)) || break
    sleep 0.1
  done
  for pid in "${pids[@]}"; do kill -KILL "$pid" 2>/dev/null; done
  wait 2>/dev/null
  [[ -n ${KEEP_TMP:-} ]] || rm -rf "$tmp"
}
trap cleanup EXIT
fail() {
  echo "FAIL: $*"
  for log in "$tmp"/*.log; do
    [[ -e $log ]] || continue
    echo "==== $log"
    tail -n 30 "$log"
  done
  exit 1
}
start=$(date +%s.%N)

# The drive: teach on the teach variant, repeat on the repeat variant (other sun, 1 m to the side) and 20 frames
# further, both as bags.
"$retrace" sim render --bag "$tmp/teach.bag" --frames "$taught" --width 320 --height 240 --quiet >/dev/null ||
  fail "sim render --bag (teach)"
"$retrace" sim render --bag "$tmp/repeat.bag" --variant repeat --frames "$frames" --width 320 --height 240 --quiet \
  >/dev/null || fail "sim render --bag (repeat)"
"$retrace" teach --sequence "$tmp/teach.bag" --map "$tmp/map.db" --no-progress >"$tmp/teach.log" 2>&1 ||
  fail "teach on the bag"
"$retrace" repeat --map "$tmp/map.db" --sequence "$tmp/repeat.bag" --topic /camera/image_raw \
  --output "$tmp/repeat.csv" --no-progress >"$tmp/repeat.log" 2>&1 || fail "repeat on the bag"
last_stamp=$(tail -n 1 "$tmp/repeat.csv" | cut -d, -f3)

# A private ROS master: a free port on localhost, everything ROS writes inside $tmp.
port=$(/usr/bin/python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
export ROS_MASTER_URI="http://127.0.0.1:$port" ROS_HOSTNAME=127.0.0.1 ROS_HOME="$tmp/ros_home" \
  ROS_LOG_DIR="$tmp/ros_log"
unset ROS_IP ROS_NAMESPACE
roscore -p "$port" >"$tmp/roscore.log" 2>&1 &
core=$!
pids+=($core)
master_up() { /usr/bin/python3 -c 'import rosgraph, sys; sys.exit(0 if rosgraph.is_master_online() else 1)' 2>/dev/null; }
for _ in $(seq 60); do
  master_up && break
  sleep 0.5
done
# Our master, not another one that took the port meanwhile (roscore exits when a master runs there).
master_up && kill -0 "$core" 2>/dev/null || fail "roscore did not start on port $port"

# Two nodes on the same camera topic, each with its own cmd_vel.
for name in every live; do
  every=false
  [[ $name == every ]] && every=true
  "$node" __name:="$name" _map:="$tmp/map.db" _speed:="$speed" _process_every_frame:="$every" \
    _diagnostics_period:=0.02 image:=/camera/image_raw cmd_vel:="/$name/cmd_vel" >"$tmp/$name.log" 2>&1 &
  pids+=($!)
done
for name in every live; do
  for _ in $(seq 120); do
    grep -q 'ready' "$tmp/$name.log" && break
    sleep 0.5
  done
  grep -q 'ready' "$tmp/$name.log" || fail "node $name did not start"
done

/usr/bin/python3 "$here/node_test.py" listen "$tmp/recorded.json" every,live "$frames" "$last_stamp" 180 \
  >"$tmp/listener.log" 2>&1 &
listener=$!
pids+=($listener)
for _ in $(seq 150); do
  grep -q listening "$tmp/listener.log" && break
  sleep 0.5
done
grep -q listening "$tmp/listener.log" || fail "the listener did not connect to the nodes' topics"
# 50x the camera's rate: `every` queues what it cannot process at once, `live` drops it. At 5x (a frame every 20 ms)
# an idle 2-core machine kept up with every frame, relocalizing ones included (8-22 ms), and `live` dropped none.
# The drive then lasts a fraction of a second: /diagnostics every 20 ms (above) so that some come while tracking.
# -d: subscribers connect before the first frame.
rosbag play -q -d 2 -r 50 --queue=1000 "$tmp/repeat.bag" --topics /camera/image_raw >"$tmp/play.log" 2>&1 ||
  fail "rosbag play"
wait "$listener" || fail "the listener failed"
/usr/bin/python3 "$here/node_test.py" compare "$tmp/recorded.json" "$tmp/repeat.csv" "$speed" || fail "comparison"
printf 'node_test: passed in %.1f s\n' "$(echo "$(date +%s.%N) - $start" | bc)"
