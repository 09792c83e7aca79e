#pragma once

// Where the key-images of a map are, from the ground truth of the drives that taught it (one per route, in route
// order): `inspect --report --ground-truth` draws the graph there and `sim navigate --taught` scores against it.
//
// Each drive is a sequence folder with a KITTI poses.txt, or the poses.txt itself. A drive recorded by `retrace sim
// render` has its scenario.yaml beside poses.txt: its world frame (the camera at the drive's start) is then moved
// into the simulated town's frame (x east, y north), which all drives of one town share. Otherwise the poses are
// taken as they are, seen from above in their world frame's x and z (a camera frame: x right, y down, z ahead), so
// drives of several routes must share one world frame (e.g. from GNSS) to be drawn together.

#include <filesystem>
#include <string>
#include <unordered_map>
#include <vector>

#include "retrace/map/map.h"
#include "retrace/util/types.h"

namespace retrace {

struct KeyImagePlaces {
  std::unordered_map<node_t, Vector2d> positions;  // metres, seen from above
  bool town_frame = false;                         // every drive had its scenario.yaml: x east, y north
  std::string x_label, y_label;                    // the axes, for plots
};

// Throws InputError naming the drive when it has no poses.txt, fewer poses than a key-image's frame, or when the
// map has more routes than drives were given.
KeyImagePlaces ReadKeyImagePlaces(const Map& map, const std::vector<std::filesystem::path>& drives);

}  // namespace retrace
