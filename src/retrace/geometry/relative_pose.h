#pragma once

// Relative pose of two calibrated views from unit bearing vectors: the 5-point essential-matrix solver (Nistér 2004;
// Stewénius et al. 2006, five_point.h) inside the robust loop of two_view_geometry.h (MSAC scoring, adaptive iterations, cheirality on the
// sample, LM refinement of R and unit t on the Sampson error, triangulation and σ_p of the inliers).
//
// Works for perspective and omnidirectional cameras alike: bearings may point anywhere on the sphere (including
// backwards in a panorama); cheirality is tested as positive distances along both rays.
//
// Example:
//   TwoViewGeometry g = EstimateRelativePose(bearings_a, bearings_b, camera.FocalLength(), TwoViewOptions());
//   if (g.success) use(g.b_from_a, g.sigma_p, g.points_in_a);
//   else           spdlog::info("no geometry: {}", g.failure_message);

#include <vector>

#include "retrace/geometry/two_view_geometry.h"

namespace retrace {

// Robust relative pose b_from_a (x_B = R x_A + t, |t| = 1) from correspondences bearings_a[i] <-> bearings_b[i]
// (unit vectors in the frames of cameras A and B). `focal_length_px` converts the pixel thresholds of `options`
// to angles (CameraModel::FocalLength()). Never throws; failures are reported in the result. When several
// correspondences are needed (5 for the solver, options.min_inliers for a result) and missing, or the inliers show
// no parallax (pure rotation), `success` is false with a reason.
// `guess`, when given, is a hypothesis b_from_a scored before any sample (e.g. the previous frame's geometry while
// tracking; RansacOptions::min_iterations_with_guess).
TwoViewGeometry EstimateRelativePose(const std::vector<Vector3d>& bearings_a, const std::vector<Vector3d>& bearings_b,
                                     double focal_length_px, const TwoViewOptions& options = TwoViewOptions(),
                                     const Rigid3d* guess = nullptr);

// Minimal solver: the candidate poses b_from_a of five correspondences `sample` (indices into the bearing lists)
// that put all five points in front of both cameras (up to 10 essential matrices, each decomposed and
// disambiguated by cheirality). Exposed for tests and benchmarks.
void SolveFivePoint(const std::vector<Vector3d>& bearings_a, const std::vector<Vector3d>& bearings_b,
                    const std::vector<int>& sample, std::vector<Rigid3d>* poses);

namespace internal {
// The 5-parameter manifold of the refinement: R <- exp(δ₀₁₂) R, t <- normalize(t + δ₃ b₁ + δ₄ b₂).
PoseManifold GeneralPoseManifold();
}  // namespace internal

}  // namespace retrace
