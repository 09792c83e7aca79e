#pragma once

// A generated, analytically defined texture with many good corners, so that tracker tests and benchmarks run
// everywhere (no real data) and images of it can be rendered EXACTLY under any scale and translation (no
// resampling error in the ground truth).
//
// The texture F(X) over the plane is painted from random axis-aligned rectangles and discs with
// Gaussian-blurred edges (rectangle masks are products of erf ramps, discs an erf ramp of the radius),
// alpha-composited over a smooth sinusoidal background.

#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "retrace/util/types.h"

namespace retrace {

struct SyntheticTextureOptions {
  double width = 640.0;  // extent of the painted area in texture units (= pixels at scale 1)
  double height = 480.0;
  int num_shapes = 600;     // rectangles and discs
  double edge_sigma = 0.8;  // Gaussian blur of the shape edges, texture units
  double min_grey =
      50.0;  // grey range (kept away from 0 and 255 so that the contrast changes of tests do not
  double max_grey = 150.0;  // saturate)
  uint64_t seed = 1;        // random seed; equal options give equal textures

  bool Check() const {
    return width > 0 && height > 0 && num_shapes >= 0 && edge_sigma > 0.0 && min_grey < max_grey;
  }
};

class SyntheticTexture {
 public:
  explicit SyntheticTexture(const SyntheticTextureOptions& options = {});

  // Renders a width x height CV_32FC1 image in which texture point X appears at pixel x = scale * X +
  // translation, with grey levels gain * F(X) + bias (pixel centres sampled, no anti-aliasing beyond the
  // blurred edges).
  cv::Mat Render(int width, int height, double scale = 1.0, const Vector2d& translation = Vector2d::Zero(),
                 double gain = 1.0, double bias = 0.0) const;

 private:
  struct Shape {
    bool disc = false;
    double x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // rectangle corners, or disc centre (x0, y0) and radius x1
    double grey = 0;
  };
  SyntheticTextureOptions options_;
  std::vector<Shape> shapes_;
  double background_fx_ = 0, background_fy_ = 0, background_px_ = 0, background_py_ = 0;
};

// A width x height 8-bit gray image of a cluttered texture (corners, blobs and edges; a shape per 500 pixels, grey
// levels 10-240) generated from `seed`: the test image of the wide-baseline and binary feature tests.
cv::Mat ClutteredTexture(int width, int height, uint64_t seed);

}  // namespace retrace
