#pragma once

// Two-view geometry between images A and B from bearing-vector correspondences: the common options and result of
// the robust estimators (5-point: relative_pose.h, planar motion: planar_pose.h) and the robust sampling loop they
// share.
//
// Robust estimation (Segvic 2009 §4.4 uses MLESAC with a 5-point generator):
//  - hypotheses come from random minimal samples; a hypothesis is kept only when every sampled correspondence is in
//    front of both cameras (cheirality on the sample, Booij 2007 §B.3 / Chum et al. 2004);
//  - a hypothesis is scored with the MSAC cost (Torr & Zisserman 2000, the truncated-quadratic form of MLESAC's
//    likelihood): Σ_i min(e_i², τ²), where e_i is the Sampson error in pixels and correspondences that triangulate
//    behind a camera cost τ². Lower cost is better; unlike inlier counting it prefers the hypothesis that fits its
//    inliers best;
//  - the number of iterations adapts to the best inlier ratio w: N = log(1 - confidence) / log(1 - w^k);
//  - the best hypothesis is refined on its inliers by Levenberg-Marquardt on the Sampson error (R and unit t), the
//    inliers are re-selected and refined again (local optimisation);
//  - inliers = Sampson error below the threshold AND triangulated in front of both cameras AND the triangulated
//    point reprojects within the threshold (both images together; this rejects the occasional outlier that lies
//    near its epipolar line far from where the rays meet);
//  - inliers are triangulated (midpoint) and σ_p (Segvic 2009, eq. 6) is computed from their reprojection residuals
//    in image B (see sigma_p.h).
//
// Pixel thresholds are converted to angles with the focal length (pixels per radian, CameraModel::FocalLength()).

#include <cstdint>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "retrace/util/types.h"

namespace retrace {

struct RansacOptions {
  // Inlier threshold τ on the Sampson error (both images together), in pixels.
  double max_error_px = 2.0;
  // Probability that at least one sample is outlier-free when the adaptive loop stops.
  double confidence = 0.999;
  // Bounds on the number of samples drawn.
  int min_iterations = 100;
  int max_iterations = 5000;
  // The lower bound when the estimator is given a guess (e.g. the previous frame's geometry while tracking): the
  // guess is scored before any sample, so a good one lets the adaptive loop stop after few samples.
  int min_iterations_with_guess = 5;
  // Seed of the random sampler; equal seeds and inputs give equal results.
  uint64_t seed = 0x5eed;

  bool Check() const;
};

struct TwoViewOptions {
  RansacOptions ransac;
  // Levenberg-Marquardt iterations of each refinement on the inliers (0 disables the refinement).
  int refinement_iterations = 10;
  // Fewer inliers than this is a failure (the 5-point model has 5 degrees of freedom).
  int min_inliers = 8;
  // Degeneracy guard: the median parallax of the inliers must reach this many pixels. Parallax is the angle between
  // f_B and R₀ f_A times the focal length, with R₀ the pure rotation that best explains the inliers: when a rotation
  // alone explains them within a couple of pixels (pure rotation, a scene at infinity, a tiny baseline), the
  // translation is not observable.
  double min_parallax_px = 2.0;
  // Tolerated probability p of σ_p (Segvic 2009, eq. 6).
  double sigma_p_probability = 0.05;
  // With a guess (the previous frame's geometry), the refined guess is kept unless a sampled hypothesis fits the
  // correspondences better by more than this fraction of its MSAC cost. Forward motion in a turn with the features
  // on one facade fits two mirrored motions almost equally (the planar ambiguity of the essential matrix): in the
  // simulated town a key-image's geometry jumped from 28 to 72 degrees of rotation for one frame and back. 0: the
  // lowest cost wins.
  double guess_preference = 0.2;

  bool Check() const;
};

enum class TwoViewFailure {
  kNone = 0,
  kInvalidOptions,
  kTooFewCorrespondences,
  kInvalidInput,          // sizes differ, non-finite or zero-length bearings, focal length <= 0
  kNoHypothesis,          // no sample produced a model with its points in front of both cameras
  kTooFewInliers,
  kInsufficientParallax,  // pure rotation, no baseline or all points at infinity
};

const char* TwoViewFailureName(TwoViewFailure failure);

// Result of a two-view estimation. Arrays indexed by correspondence have the size of the input; entries of
// non-inliers are zero. On failure `success` is false and `failure`/`failure_message` say why; for
// kInsufficientParallax the other fields still describe the (unreliable) estimate, for diagnostics.
struct TwoViewGeometry {
  bool success = false;
  TwoViewFailure failure = TwoViewFailure::kNone;
  std::string failure_message;  // empty on success

  // Relative pose: x_B = R x_A + t, |t| = 1 (unit baseline).
  Rigid3d b_from_a;

  std::vector<bool> inlier_mask;
  int num_inliers = 0;
  // Triangulated inliers in A's frame, in units of the baseline, and their distances along the rays of A and B.
  std::vector<Vector3d> points_in_a;
  std::vector<double> depths_a;
  std::vector<double> depths_b;

  // Segvic 2009, eq. (6), from the reprojection residuals of the inliers in image B, pixels.
  double sigma_p = std::numeric_limits<double>::infinity();
  // sqrt(Σ (Δx² + Δy²) / 2n): RMS of the same residual components, pixels.
  double rms_residual_px = std::numeric_limits<double>::infinity();
  // Median parallax of the inliers w.r.t. their best pure rotation, pixels (see TwoViewOptions::min_parallax_px).
  double median_parallax_px = 0.0;
  // Samples drawn by the robust loop.
  int num_iterations = 0;
};

namespace internal {

// Produces candidate poses from the sampled correspondence indices; every candidate must already have its sample in
// front of both cameras.
using MinimalSolver = std::function<void(const std::vector<int>& sample, std::vector<Rigid3d>* poses)>;

// A local parametrisation of the model around a pose: `dim` parameters, Update(pose, delta) -> new pose.
struct PoseManifold {
  int dim = 5;
  std::function<Rigid3d(const Rigid3d& pose, const double* delta)> update;
};

// Samples needed so that one of them is outlier-free with probability `confidence`, at this inlier ratio:
// log(1 - confidence) / log(1 - inlier_ratio^sample_size) (0 when all are inliers, INT_MAX when none is).
int RequiredIterations(double inlier_ratio, int sample_size, double confidence);
// True when every bearing is a finite unit vector.
bool ValidBearings(const std::vector<Vector3d>& bearings);

// The robust loop, refinement and final evaluation shared by the 5-point and planar estimators. `guess`, when given,
// is scored as the first hypothesis (see RansacOptions::min_iterations_with_guess).
TwoViewGeometry EstimateTwoView(const std::vector<Vector3d>& bearings_a, const std::vector<Vector3d>& bearings_b,
                                double focal_length_px, const TwoViewOptions& options, int sample_size,
                                const MinimalSolver& solver, const PoseManifold& manifold,
                                const Rigid3d* guess = nullptr);

// Central-difference Jacobian (step 1e-7) of `residuals` (fills its vector of `rows` values at a pose) over the
// manifold's parameters at `pose`: rows x manifold.dim.
using PoseResiduals = std::function<void(const Rigid3d& pose, Eigen::VectorXd* residuals)>;
Eigen::MatrixXd NumericJacobian(const PoseResiduals& residuals, const Rigid3d& pose, const PoseManifold& manifold,
                                int rows);

// Levenberg-Marquardt on the Sampson residuals (radians) of `indices` over the manifold, with an optional Cauchy
// loss of scale `cauchy_scale` (radians; 0, the default used by the estimators, is plain least squares: on a clean
// inlier set it is the maximum-likelihood estimate, while a robust loss moved the optimum of these weakly
// conditioned problems noticeably); returns the refined pose.
Rigid3d RefineOnSampson(const std::vector<Vector3d>& bearings_a, const std::vector<Vector3d>& bearings_b,
                        const std::vector<int>& indices, const Rigid3d& initial, const PoseManifold& manifold,
                        int max_iterations, double cauchy_scale = 0.0);

}  // namespace internal

// Fills inliers, triangulated points, depths, residuals, σ_p and parallax of `geometry` for its pose `b_from_a`,
// with the inlier definition of the estimators (see above, threshold max_error_px). Also
// useful to evaluate a geometry on a new set of correspondences.
void EvaluateTwoViewGeometry(const std::vector<Vector3d>& bearings_a, const std::vector<Vector3d>& bearings_b,
                             double focal_length_px, double max_error_px, double sigma_p_probability,
                             TwoViewGeometry* geometry);

// Whether the correspondence of bearings (a, b) is an inlier of the pose `b_from_a` by the same test (threshold
// max_error_px): a match found otherwise, checked against a geometry verified on other matches.
bool IsInlierOfPose(const Rigid3d& b_from_a, const Vector3d& bearing_a, const Vector3d& bearing_b,
                    double focal_length_px, double max_error_px);

}  // namespace retrace
