#pragma once

// Relative scale between two geometries that share a camera (Segvic 2009 §4.4; design §3.3).
//
// Each two-view geometry has its own unit (|t| = 1). Two geometries that share an image differ by one scalar: a point
// seen in both is at distance d₁ from the shared camera in the units of geometry 1 and at d₂ in the units of
// geometry 2, so it votes for s = d₁ / d₂. Noise and outliers make the votes differ; the robust result is their
// median.

#include <vector>

#include "retrace/util/types.h"

namespace retrace {

struct ScaleEstimate {
  bool success = false;
  // s such that (length in geometry 1) = s * (length in geometry 2).
  double scale = 0.0;
  // Number of valid votes (both distances positive and finite).
  int num_votes = 0;
  // Median absolute deviation of the log-votes: a robust relative spread (0.01 ≈ 1 %).
  double log_mad = 0.0;
};

// Median of the ratios distances_1[i] / distances_2[i] over the pairs where both are positive and finite. Fails
// (success = false) when the sizes differ or fewer than `min_votes` votes are valid.
ScaleEstimate EstimateScaleFromDistances(const std::vector<double>& distances_1,
                                         const std::vector<double>& distances_2, int min_votes = 1);

// Same from 3D points of the shared features: points_1[i] in frame 1 and points_2[i] in frame 2; the shared camera
// is at shared_from_1 in frame 1 and at shared_from_2 in frame 2. Votes use the distances from the shared camera
// centre (= depths along its rays), which also works for omnidirectional cameras.
ScaleEstimate EstimateScale(const std::vector<Vector3d>& points_1, const Rigid3d& shared_from_1,
                            const std::vector<Vector3d>& points_2, const Rigid3d& shared_from_2, int min_votes = 1);

}  // namespace retrace
