#pragma once

// Synthetic two-view scenes with ground truth, for tests and benchmarks of the geometry layer.
//
// Points are drawn through the pixels of camera A (uniformly over its image, so for a panorama they surround the
// camera, including behind it) at distances in [min_distance, max_distance], kept when they are seen by camera B
// (projectable and inside its image), then observed in both images with Gaussian pixel noise and lifted to bearings
// through the same camera model. A fraction of the correspondences is replaced by outliers (a uniformly random pixel
// in image B).

#include <cstdint>
#include <vector>

#include "retrace/camera/camera_model.h"
#include "retrace/util/types.h"

namespace retrace {

struct SyntheticTwoViewOptions {
  // Number of correspondences (inliers + outliers).
  int num_points = 100;
  // Standard deviation of the pixel noise added to each coordinate in both images.
  double noise_px = 0.5;
  // Fraction of correspondences replaced by outliers.
  double outlier_ratio = 0.3;
  // Range of distances of the points from camera A (same unit as the translation of the pose).
  double min_distance = 4.0;
  double max_distance = 30.0;
  // Seed of the generator.
  uint64_t seed = 7;

  bool Check() const;
};

struct SyntheticTwoView {
  Rigid3d b_from_a;
  // Per correspondence: true 3D point (A's frame; meaningless for outliers), noisy pixels and their bearings.
  std::vector<Vector3d> points_in_a;
  std::vector<Vector2d> pixels_a;
  std::vector<Vector2d> pixels_b;
  std::vector<Vector3d> bearings_a;
  std::vector<Vector3d> bearings_b;
  std::vector<bool> is_outlier;
};

// A scene seen by `camera` from A and from B = b_from_a * A. Returns fewer than num_points correspondences only
// when the two views barely overlap (gives up after 1000 draws per point).
SyntheticTwoView GenerateTwoView(const CameraModel& camera, const Rigid3d& b_from_a,
                                 const SyntheticTwoViewOptions& options);

}  // namespace retrace
