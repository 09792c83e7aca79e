#pragma once

// The appearance graph seen from above (Booij 2007 Figs. B.5 and B.6): key-images as points coloured by route,
// arcs as lines whose darkness is their similarity S_ij (joins between routes in green), and a planned path in red.
// Key-images are placed where GraphDrawingOptions::positions says (ground truth), else by chaining the arc
// geometries from the first node (teach/map_report.h ChainKeyImagePoses: one unit per arc where no relative scale is
// stored, so routes joined to each other are drawn at roughly, not truly, their place); key-images the chain does
// not reach are left out.

#include <string>
#include <unordered_map>

#include <opencv2/core.hpp>

#include "retrace/map/map.h"
#include "retrace/nav/graph_planner.h"

namespace retrace {

struct GraphDrawingOptions {
  int width = 900;  // pixels
  int height = 900;
  std::string title = "appearance graph";
  // Key-images at these places (e.g. ground truth, metres, seen from above) instead of the chained layout; axes
  // labelled with `x_label`, `y_label`.
  std::unordered_map<node_t, Vector2d> positions;
  std::string x_label = "x (m)", y_label = "y (m)";
};

// The graph of `map` with `path` (may be empty) drawn on it, BGR.
cv::Mat DrawPlanningGraph(const Map& map, const PlannedPath& path, const GraphDrawingOptions& options = {});

}  // namespace retrace
