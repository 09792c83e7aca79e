# shellcheck shell=bash
# CLI checks of `retrace two-view` (sourced by cli_test.sh: $bin, $data, $tmp, expect).

printf 'P0: 500 0 320 0 0 500 240 0 0 0 1 0\n' > "$tmp/two_view_calib.txt"
expect two-view-missing-image 1 "^retrace: error: $tmp/no_such_a.png: cannot read image \\(no such file\\)$" -- \
  "$bin" two-view "$tmp/no_such_a.png" "$tmp/no_such_b.png" --camera "$tmp/two_view_calib.txt"
expect two-view-needs-camera 106 "--camera is required" -- "$bin" two-view a.png b.png
head -c 100 /dev/urandom > "$tmp/garbage.png"
expect two-view-corrupt-image 1 "^retrace: error: $tmp/garbage.png: cannot read image$" -- \
  "$bin" two-view "$tmp/garbage.png" "$tmp/garbage.png" --camera "$tmp/two_view_calib.txt"

if [[ -d $data/kitti07 ]]; then
  k=$data/kitti07
  expect two-view-missing-second 1 "^retrace: error: $tmp/no_such_b.png: cannot read image \\(no such file\\)$" -- \
    "$bin" two-view "$k/image_0/000000.png" "$tmp/no_such_b.png" --camera "$k/calib.txt"
  # JSON parses and its rotation is within 0.3 deg of the ground truth b_from_a = world_from_b^-1 world_from_a
  # (poses.txt lines 1 and 11: frames 0 and 10), its translation direction within 3 deg.
  check_two_view_json() {
    "$bin" two-view "$k/image_0/000000.png" "$k/image_0/000010.png" --camera "$k/calib.txt" --json |
      python3 -c '
import json, math, sys
out = json.load(sys.stdin)
assert set(out) == {"R", "t", "inliers", "sigma_p"}, out.keys()
lines = open(sys.argv[1]).read().split("\n")
def pose(i):
    v = [float(x) for x in lines[i].split()]
    return [v[0:3], v[4:7], v[8:11]], [v[3], v[7], v[11]]
(ra, ta), (rb, tb) = pose(0), pose(10)
# b_from_a: R = Rb^T Ra, t = Rb^T (ta - tb)
R = [[sum(rb[k][i] * ra[k][j] for k in range(3)) for j in range(3)] for i in range(3)]
t = [sum(rb[k][i] * (ta[k] - tb[k]) for k in range(3)) for i in range(3)]
E = out["R"]
trace = sum(R[k][i] * E[3 * k + i] for i in range(3) for k in range(3))  # trace(R_true^T R_est)
rot = math.degrees(math.acos(max(-1.0, min(1.0, (trace - 1) / 2))))
n = math.sqrt(sum(x * x for x in t))
cos_t = sum(a * b for a, b in zip(out["t"], t)) / n / math.sqrt(sum(x * x for x in out["t"]))
trans = math.degrees(math.acos(max(-1.0, min(1.0, cos_t))))
print("rotation error %.3f deg, translation error %.3f deg, %d inliers, sigma_p %.3f" % (rot, trans, out["inliers"], out["sigma_p"]))
sys.exit(0 if rot < 0.3 and trans < 3.0 and out["inliers"] > 100 else 1)
' "$k/poses.txt"
  }
  expect two-view-kitti-json 0 '^rotation error 0\.[0-9]+ deg, translation error [0-2]\.[0-9]+ deg' -- check_two_view_json
  expect two-view-kitti-text 0 'inliers: +[0-9]{3,}' -- \
    "$bin" two-view "$k/image_0/000050.png" "$k/image_0/000060.png" --camera "$k/calib.txt"
fi
