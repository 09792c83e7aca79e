# Graph navigation (issue 15): similarity and route in `inspect --json`, `teach --append`, `retrace plan`, and the
# heading of `two-view --planar --json`.
if [[ -d $data/kitti07 ]]; then
  k=$data/kitti07
  # The even frames at 320 px, then the odd frames of the same drive appended as route 1: the same places, so the
  # two routes are joined; both use the frames of one drive, so poses.txt is the ground truth of every join.
  expect append-base 0 'key-images' -- "$bin" teach --sequence "$k" --map "$tmp/graph.db" --every 2 --width 320 \
    --no-progress
  expect append-odd 0 'appended as route 1 .*: [1-9][0-9]* join arcs' -- "$bin" teach --sequence "$k" \
    --map "$tmp/graph.db" --every 2 --offset 1 --append --no-progress
  # Every arc has a similarity in (0, 1] and every node its route; every join links route 1 to route 0 with a
  # geometry within 5 deg (rotation) and 10 deg (translation direction) of the ground truth.
  check_graph_json() {
    "$bin" inspect --map "$tmp/graph.db" --json | python3 -c '
import json, math, sys
m = json.load(sys.stdin)
route = {n["id"]: n["route"] for n in m["nodes"]}
frame = {n["id"]: n["source_frame"] for n in m["nodes"]}
assert set(route.values()) == {0, 1}, set(route.values())
assert all(frame[i] % 2 == route[i] for i in route)  # route 0: even frames, route 1: odd frames
lines = open(sys.argv[1]).read().split("\n")
def pose(i):
    v = [float(x) for x in lines[i].split()]
    return [v[0:3], v[4:7], v[8:11]], [v[3], v[7], v[11]]
joins, worst_rot, worst_dir = 0, 0.0, 0.0
for a in m["arcs"]:
    assert a["similarity"] is not None and 0 < a["similarity"] <= 1, a
    if a["kind"] != "join":
        assert route[a["from"]] == route[a["to"]], a
        continue
    joins += 1
    assert route[a["from"]] == 1 and route[a["to"]] == 0 and a["similarity"] >= 0.05, a
    (ra, ta), (rb, tb) = pose(frame[a["from"]]), pose(frame[a["to"]])
    R = [[sum(rb[k][i] * ra[k][j] for k in range(3)) for j in range(3)] for i in range(3)]
    t = [sum(rb[k][i] * (ta[k] - tb[k]) for k in range(3)) for i in range(3)]
    E = a["R"]
    trace = sum(R[k][i] * E[3 * k + i] for i in range(3) for k in range(3))
    rot = math.degrees(math.acos(max(-1.0, min(1.0, (trace - 1) / 2))))
    n = math.sqrt(sum(x * x for x in t))
    d = math.degrees(math.acos(max(-1.0, min(1.0, sum(x * y for x, y in zip(a["t"], t)) / n)))) if n > 1 else 0.0
    worst_rot, worst_dir = max(worst_rot, rot), max(worst_dir, d)
print("%d joins, worst rotation %.2f deg, worst direction %.2f deg" % (joins, worst_rot, worst_dir))
sys.exit(0 if joins > 0 and worst_rot < 5 and worst_dir < 10 else 1)
' "$k/poses.txt"
  }
  expect append-joins-true 0 '^[1-9][0-9]* joins, worst rotation' -- check_graph_json
  # A drive of another camera is refused, and the map stays as it was.
  sed 's/^P0: 7.070912000000e+02/P0: 6.0e+02/' "$k/calib.txt" >"$tmp/other_calib.txt"
  before=$(md5sum <"$tmp/graph.db")
  expect append-other-camera 1 "^retrace: error: $k: not recorded with the map's camera" -- "$bin" teach \
    --sequence "$k" --camera "$tmp/other_calib.txt" --map "$tmp/graph.db" --every 2 --append --no-progress
  expect append-map-intact 0 '' -- bash -c "[[ '$before' == \"\$(md5sum <'$tmp/graph.db')\" ]]"
  expect append-missing-map 1 "^retrace: error: $tmp/none.db: no such map to append to$" -- "$bin" teach \
    --sequence "$k" --map "$tmp/none.db" --append --no-progress
  # Planning from the first key-image of route 0 to the last of route 1 crosses over a join.
  check_plan_json() {
    last=$("$bin" inspect --map "$tmp/graph.db" --json | python3 -c '
import json, sys
print(max(n["id"] for n in json.load(sys.stdin)["nodes"]))')
    "$bin" plan --map "$tmp/graph.db" --from 0 --to "$last" --json | python3 -c '
import json, sys
p = json.load(sys.stdin)
assert p["path"][0] == 0 and p["path"][-1] == int(sys.argv[1]) and p["cost"] > 0, p
assert len(p["arcs"]) == len(p["path"]) - 1
print("path of %d key-images, cost %.2f" % (len(p["path"]), p["cost"]))' "$last"
  }
  expect plan-json 0 '^path of [0-9]+ key-images, cost' -- check_plan_json
  expect plan-report 0 'plan.png' -- "$bin" plan --map "$tmp/graph.db" --from 0 --to 3 --report "$tmp/plan"
  expect plan-drive-cost 0 'drive cost' -- "$bin" plan --map "$tmp/graph.db" --from 0 --to 3 --cost drive
  expect plan-unknown-node 1 "^retrace: error: $tmp/graph.db: no key-image 9999 in the map" -- "$bin" plan \
    --map "$tmp/graph.db" --from 0 --to 9999
  # A map written before similarities were stored (schema 2) still opens; the appearance cost needs them.
  cp "$tmp/graph.db" "$tmp/schema2.db"
  python3 -c '
import sqlite3, sys
c = sqlite3.connect(sys.argv[1])
c.executescript("ALTER TABLE nodes DROP COLUMN route; ALTER TABLE arcs DROP COLUMN similarity; PRAGMA user_version=2;")
c.close()' "$tmp/schema2.db"
  expect plan-old-map 1 "^retrace: error: $tmp/schema2.db: arc 0 has no similarity" -- "$bin" plan \
    --map "$tmp/schema2.db" --from 0 --to 3
  expect plan-old-map-drive 0 'path from 0 to 3' -- "$bin" plan --map "$tmp/schema2.db" --from 0 --to 3 --cost drive
  expect inspect-old-map 0 'similarity +not stored' -- "$bin" inspect --map "$tmp/schema2.db"
  # The graph at the key-images' true places needs the ground truth of every route (here one drive for both).
  expect inspect-truth-per-route 1 "^retrace: error: $k: the map has route 1 .* ground truth of 1 drive" -- "$bin" \
    inspect --map "$tmp/graph.db" --report "$tmp/graph_report" --ground-truth "$k"
  expect inspect-truth-graph 0 'graph.png' -- "$bin" inspect --map "$tmp/graph.db" --report "$tmp/graph_report" \
    --ground-truth "$k" "$k/poses.txt"
  # sim navigate refuses a goal the map does not have, a bad option and a scenario whose camera did not take the
  # key-images.
  expect navigate-missing-goal 1 "^retrace: error: $tmp/graph.db: has no key-image 99999 \\(--goal" -- "$bin" sim \
    navigate --map "$tmp/graph.db" --goal 99999 --out "$tmp/navigate" --quiet
  expect navigate-bad-branch-probability 1 "^retrace: error: sim navigate options: localizer: .*planned_branch_probability must be in \\(0, 1\\)" \
    -- "$bin" sim navigate --map "$tmp/graph.db" --goal 0 --out "$tmp/navigate" --planned-branch-probability 1 --quiet
  expect navigate-camera-mismatch 1 "graph.db: key-images are 320x97 but the scenario's camera is 64x48" -- "$bin" \
    sim navigate --map "$tmp/graph.db" --goal 0 --out "$tmp/navigate" --width 64 --height 48 --quiet
  # sim drive starts on the route's first arc unless told another; an arc the map does not have is refused.
  expect drive-bad-start-arc 1 "^retrace: error: $tmp/graph.db: --start-arc 99999: the map has no such arc" -- \
    "$bin" sim drive --map "$tmp/graph.db" --out "$tmp/drive" --width 320 --height 97 --start-arc 99999 --quiet
fi
# two-view --planar --json: the heading (eq. B.4 in retrace's axes: atan2(c_x, c_z) of B's centre c in A's camera
# frame) in the simulator with a level camera on flat ground (the planar model's setting), in the left turn of the
# default route: frames 84 -> 92 and 90 -> 98, within 0.05 rad of the ground truth.
printf 'vehicle:\n  camera_tilt_deg: 0\ncamera:\n  width: 320\n  height: 240\n' >"$tmp/level.yaml"
expect heading-render 0 'wrote 100 frames' -- "$bin" sim render --scenario "$tmp/level.yaml" --out "$tmp/level" \
  --frames 100
check_heading() {
  "$bin" two-view "$tmp/level/image_0/0000$1.png" "$tmp/level/image_0/0000$2.png" --camera "$tmp/level/camera.yaml" \
    --planar --json | python3 -c '
import json, math, sys
out = json.load(sys.stdin)
lines = open(sys.argv[1]).read().split("\n")
def pose(i):
    v = [float(x) for x in lines[i].split()]
    return [v[0:3], v[4:7], v[8:11]], [v[3], v[7], v[11]]
(ra, ta), (rb, tb) = pose(int(sys.argv[2])), pose(int(sys.argv[3]))
c = [sum(ra[k][i] * (tb[k] - ta[k]) for k in range(3)) for i in range(3)]  # centre of B in A: Ra^T (tb - ta)
truth = math.atan2(c[0], c[2])
error = abs(math.remainder(out["heading"] - truth, 2 * math.pi))
print("heading %.4f rad, truth %.4f rad, error %.4f rad" % (out["heading"], truth, error))
sys.exit(0 if error < 0.05 and abs(truth) > 0.2 else 1)' "$tmp/level/poses.txt" "$1" "$2"
}
expect two-view-planar-heading-84 0 '^heading -.* error 0\.0[0-4]' -- check_heading 84 92
expect two-view-planar-heading-90 0 '^heading -.* error 0\.0[0-4]' -- check_heading 90 98
# sim render --poses: frames at given camera poses (world frame of the scenario), written with those poses.
printf '1 0 0 0 0 1 0 -1.5 0 0 1 10\n0 0 1 1 0 1 0 -1.5 -1 0 0 11\n' >"$tmp/two_poses.txt"
expect render-poses 0 'wrote 2 frames at the poses of' -- "$bin" sim render --poses "$tmp/two_poses.txt" \
  --out "$tmp/at_poses" --width 80 --height 60 --quiet
expect render-poses-written 0 '' -- bash -c "[[ -f '$tmp/at_poses/image_0/000001.png' ]] && \
  python3 -c 'import sys; a = [[float(x) for x in l.split()] for l in open(sys.argv[1])]; \
b = [[float(x) for x in l.split()] for l in open(sys.argv[2])]; \
sys.exit(0 if len(a) == len(b) == 2 and all(abs(x - y) < 1e-9 for p, q in zip(a, b) for x, y in zip(p, q)) else 1)' \
  '$tmp/two_poses.txt' '$tmp/at_poses/poses.txt'"
expect render-poses-missing 1 "^retrace: error: $tmp/no_poses.txt" -- "$bin" sim render --poses "$tmp/no_poses.txt" \
  --out "$tmp/at_poses2" --quiet
expect render-poses-bag 1 'give --out FOLDER \(not --bag\)' -- "$bin" sim render --poses "$tmp/two_poses.txt" \
  --bag "$tmp/x.bag" --quiet
