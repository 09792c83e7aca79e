# shellcheck shell=bash
# Kidnapped starts along a repeated facade (issues 13 and 16: never a wrong place), sourced by cli_test.sh ($bin,
# $tmp, expect). The validation drive of seed 2 (`scripts/validation seed2`: the town and route of seed 2, 8 m/s,
# 10 Hz, the repeat 1 m beside under the afternoon sun), taught as the validation matrix teaches it. Its frame 170
# verifies key-image 25, 0.8 m ahead, with 65 inliers and key-image 27, 10 m ahead, with 67: the frame's key-points on
# the facade to the right match that key-image's one or two windows along, a shift along the epipolar lines that the
# relative pose does not refute, and the mapped features located through those matches (14-24 pixels off) put the
# camera 10 m ahead. Before a key-image near the best one that verified almost as well was weighed by the features each
# locates, the twenty starts at frames 160-179 reported 3 frames of 2 starts two arcs ahead (and localized 18 of 20
# within three frames; 20 now).
kn=$tmp/kidnap
mkdir -p "$kn"
kidnap_drive=(--seed 2 --speed 8 --frame-rate 10 --pedestrians 12 --route auto --segments 8 --width 320 --height 240
  --quiet)
"$bin" sim render "${kidnap_drive[@]}" --frames 300 --out "$kn/teach" --variant teach >/dev/null
"$bin" sim render "${kidnap_drive[@]}" --frames 185 --lateral-offset 1 --out "$kn/repeat" --variant repeat >/dev/null
"$bin" teach --sequence "$kn/teach" --map "$kn/map.db" --no-progress >/dev/null 2>&1
expect kidnap-repeated-facade 0 \
  "kidnap: 20 starts on a map of 46 key-images .* within 3 frames (19|20) \([0-9.]+ %\); 0 wrong frames in 0 starts" -- \
  "$bin" bench kidnap --map "$kn/map.db" --sequence "$kn/repeat" --at $(seq -s ' ' 160 179) --frames 3
