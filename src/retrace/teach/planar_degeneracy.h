#pragma once

// Does a two-view geometry rest on one plane, so that the pair does not determine the motion? (issue 18: teach writes
// no geometry it cannot support)
//
// When the correspondences of a pair lie on one plane (an empty ground of fine texture, a pavement of identical
// slabs), the images are related by a homography H = R + t nᵀ / d, and H decomposes into two motions that both put
// the points in front of the cameras (Faugeras & Lustman 1988; Hartley & Zisserman 2003 §13.3.1; here
// cv::decomposeHomographyMat). The essential matrix fits either, and with noise a family around them: on a plane of
// paving slabs the tracked arcs came out 95-110 degrees off the truth with σ_p 0.1 px, on fine ground texture gap
// arcs 50-80 degrees off (teacher_degenerate_test). σ_p cannot see it: both motions fit.
//
// The test asks the data directly whether they tell the plane's motions apart. The dominant plane is the homography
// that explains most of the motion's inliers (MSAC over random 4-samples, DLT on bearings, refined on its inliers);
// a point lies on it when its distance to it (both images, pixels: the symmetric transfer error over 4, the distance
// to the homography's manifold to first order between nearby views) is within the 95 % bound of the noise,
// e² <= 5.991 σ² (χ² with 2 degrees of freedom), σ estimated from the motion's own Sampson errors (e² / σ² is χ² with
// 1 degree of freedom: σ² = median e² / 0.4549). Each motion the dominant plane decomposes into that is another
// motion than the estimate (rotation or translation direction beyond the link limits of teach) is refined on the
// correspondences it explains (Sampson error, two refinements), and its MSAC cost over all correspondences is
// compared with the estimate's. The pair is **ambiguous** when the plane holds at least half of the inliers and such
// a motion fits within `preference` of the estimate's cost (the estimator's own rule for preferring one motion to
// another, TwoViewOptions::guess_preference). No constant is fitted to a data set.
//
// Torr's geometric robust information criterion (GRIC; Torr 1998, Phil. Trans. R. Soc. A 356) is reported with it,
// not decisive: GRIC(M) = Σ ρ(e² / σ²) + λ₁ d n + λ₂ k, ρ(x) = min(x, λ₃ (r - d)), r = 4, λ₁ = ln 4, λ₂ = ln(4n),
// λ₃ = 2; E: d = 3, k = 5; H: d = 2, k = 8. It asks which model is likelier, not whether the motion is determined:
// in the simulated town, tracked arcs in turns (a facade and the ground) made GRIC prefer the homography although the
// plane's other motion cost 5-60 times more, and it needs about 40 points to prefer H on exactly planar data.

#include <vector>

#include "retrace/util/types.h"

namespace retrace {

struct PlanarDegeneracyOptions {
  // Homography samples drawn (4 correspondences each) over the motion's inliers. Deterministic (fixed seed).
  int homography_samples = 200;
  // A correspondence is an inlier of the homography when its distance to it (both images, pixels; see above) is
  // below this; the motion's inlier threshold is the natural choice (teach passes it).
  double inlier_threshold_px = 1.5;
  // Floor of the noise σ (pixels), so that exact synthetic data do not divide by zero.
  double min_sigma_px = 1e-3;
  // Another motion of the plane is a different one when its rotation or translation direction lies this far from
  // the estimate's (degrees).
  double distinct_rotation_deg = 2.5;
  double distinct_direction_deg = 10.0;
  // ... and it fits alike when its MSAC cost is at most (1 + preference) times the estimate's.
  double preference = 0.2;
  uint64_t seed = 0x9a11;
};

struct PlanarDegeneracy {
  int num_points = 0;               // the motion's inliers
  int homography_inliers = 0;       // of those, on the best homography's plane within the noise (95 %)
  double sigma_px = 0.0;            // noise estimated from the motion's residuals
  double gric_essential = 0.0;
  double gric_homography = 0.0;
  // Reported only: GRIC prefers the homography, or it leaves fewer than a minimal sample of points off its plane.
  bool planar = false;
  // The decision: the plane holds at least half of the inliers and another of its motions fits all correspondences
  // alike (see above). The best such motion's cost over the estimate's, and how far it lies from the estimate.
  bool ambiguous = false;
  double alternative_cost_ratio = 0.0;
  double alternative_rotation_deg = 0.0;
  double alternative_direction_deg = 0.0;
};

// Points off the plane needed to single out one motion: the 5-point minimal sample (for `planar`).
constexpr int kMinimalSample = 5;

// Tests the inliers (`inlier_mask`) of the motion `b_from_a` between bearings_a[i] and bearings_b[i] (unit vectors)
// for planar degeneracy, and all correspondences for a second motion of the plane that fits them alike (ambiguous).
// `focal_length_px` converts angles to pixels (CameraModel::FocalLength()).
PlanarDegeneracy TestPlanarDegeneracy(const std::vector<Vector3d>& bearings_a, const std::vector<Vector3d>& bearings_b,
                                      const std::vector<bool>& inlier_mask, const Rigid3d& b_from_a,
                                      double focal_length_px, const PlanarDegeneracyOptions& options = {});

}  // namespace retrace
