#pragma once

// Multi-scale corner detection (Shi-Tomasi minimum eigenvalue, or Harris) on an ImagePyramid.
//
// The mapper initialises the tracker "with all Harris corners in the initial frame" (Segvic 2009, §5.1.1) and
// the wide-baseline matcher uses multi-scale Harris key-points (§4.1). Here the corner score is computed on
// every detection level of the (pre-smoothed) pyramid, local maxima above `quality_level` times the strongest
// response of their level are collected, and the strongest ones are kept greedily with a minimum distance
// between them (in level-0 pixels), inside an optional mask and away from already tracked points. Corners
// found on coarse levels are reported at level-0 pixels; their `level` says where they were found.

#include <opencv2/core.hpp>
#include <vector>

#include "retrace/feature/image_pyramid.h"
#include "retrace/util/types.h"

namespace retrace {

struct CornerDetectorOptions {
  // Maximum number of corners returned (strongest first); <= 0 means no limit.
  int max_corners = 300;
  // Minimum distance (level-0 pixels) between two returned corners and between a corner and an `existing`
  // point.
  double min_distance = 8.0;
  // Keep a local maximum when its score is at least this fraction of the strongest score of its level.
  double quality_level = 0.01;
  // Side (pixels of the level) of the window over which the structure tensor is summed.
  int block_size = 5;
  // Pyramid levels searched (1 = level 0 only); limited by the pyramid's number of levels.
  int num_scales = 1;
  // Corners closer than this to the image border (level-0 pixels) are dropped; it should be at least half the
  // tracker window plus one so that a reference patch can be cut around every corner.
  int border = 9;
  // Harris response det - k trace^2 instead of the Shi-Tomasi minimum eigenvalue.
  bool use_harris = false;
  // Harris constant k.
  double harris_k = 0.04;

  bool Check() const {
    return min_distance >= 0.0 && quality_level > 0.0 && quality_level < 1.0 && block_size >= 2 &&
           num_scales >= 1 && border >= 0 && harris_k > 0.0;
  }
};

struct Corner {
  Vector2d position = Vector2d::Zero();  // level-0 pixels (centre of the top-left pixel is (0, 0))
  double score = 0.0;                    // score relative to the strongest response of its level, in (0, 1]
  int level = 0;                         // pyramid level where the corner was found
};

// Detects corners in `pyramid`, strongest first. `mask` (optional, CV_8UC1 of the level-0 size): corners only
// where it is non-zero. `existing` (optional): positions that new corners must keep `min_distance` away from
// (e.g. the features tracked already).
std::vector<Corner> DetectCorners(const ImagePyramid& pyramid, const CornerDetectorOptions& options,
                                  const cv::Mat& mask = cv::Mat(),
                                  const std::vector<Vector2d>& existing = {});

}  // namespace retrace
