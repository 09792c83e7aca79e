#pragma once

// Absolute pose of a calibrated camera from 2D-3D correspondences on unit bearing vectors: where a camera is
// in a reconstruction. Repeat uses it to place the current camera in the reconstruction of the current arc
// (the points Q_kj of W_k, stored in the map), which fixes the camera's position in the arc's own frame and
// unit directly, without the separate scale estimate of the decomposed point transfer (point_transfer.h).
//
// Robust estimation, as for the two-view geometries (two_view_geometry.h):
//  - hypotheses from random minimal samples of three correspondences, solved by Grunert's P3P (Haralick et al.,
//    IJCV 1994; p3p.h), up to four poses each;
//  - MSAC scoring, Σ_i min(e_i², τ²), with e_i the angle between the observed bearing and the direction to
//    the point in the camera, times the focal length (pixels); a point behind the camera (on the wrong side
//    along its ray) costs τ²;
//  - adaptive number of samples from the best inlier ratio, N = log(1 - confidence) / log(1 - w³);
//  - the best hypothesis is refined on its inliers by Levenberg-Marquardt on the same residuals (analytic
//    Jacobian), inliers re-selected and refined again while the inlier set grows;
//  - σ_p (Segvic 2009, eq. (6)) from the inliers' residual components in the tangent plane of each observed
//    bearing, in pixels (sigma_p.h): the same quality measure and the same gate as the two-view geometries.
//
// Works for perspective and omnidirectional cameras (bearings anywhere on the sphere).
//
// Example:
//   AbsolutePose pose = EstimateAbsolutePose(points_in_arc, bearings_now, camera.FocalLength(), options);
//   if (pose.success) use(pose.cam_from_world, pose.sigma_p);

#include <limits>
#include <string>
#include <vector>

#include "retrace/geometry/two_view_geometry.h"
#include "retrace/util/types.h"

namespace retrace {

struct AbsolutePoseOptions {
  // Sampling: τ = max_error_px (angle times focal length), confidence, sample bounds, seed. Tracked features
  // have few outliers, so the minimum number of samples is low.
  RansacOptions ransac = [] {
    RansacOptions r;
    r.min_iterations = 20;
    return r;
  }();
  // Fewer inliers than this is a failure: the pose has 6 degrees of freedom, and a few more points make σ_p
  // (which penalises small supports) meaningful.
  int min_inliers = 6;
  // Rounds of refinement and re-selection of the inliers, and Levenberg-Marquardt iterations per round.
  int refinement_rounds = 3;
  int refinement_iterations = 10;
  // Tolerated probability p of σ_p (Segvic 2009, eq. (6)).
  double sigma_p_probability = 0.05;
  // With point covariances (EstimateAbsolutePose): true, the estimate, its inliers and σ_p weigh each residual by
  // them; false, the estimate, inliers and σ_p are those of exact points and only the covariance includes the
  // points' errors — the sandwich A⁻¹ B A⁻¹ of the least-squares estimate (A its normal matrix, B the same with each
  // residual's covariance I + J_X Σ_X J_Xᵀ), scaled by the unit variance of the whitened residuals.
  bool weigh_by_point_covariances = true;

  bool Check(std::string* error = nullptr) const;
};

struct AbsolutePose {
  bool success = false;
  std::string failure_message;  // empty on success

  // x_cam = R x_world + t, in the unit of the given points.
  Rigid3d cam_from_world;
  std::vector<bool> inlier_mask;  // per correspondence
  int num_inliers = 0;
  // Segvic 2009, eq. (6), from the inliers' residuals (whitened by the points' covariances when given), pixels.
  double sigma_p = std::numeric_limits<double>::infinity();
  // RMS of the inliers' residual components (whitened likewise), pixels.
  double rms_residual_px = std::numeric_limits<double>::infinity();
  // Covariance of the camera centre C = -Rᵀt in the world frame (unit of the points²), first order: s² (JᵀJ)⁻¹ of
  // the refinement's normal equations restricted to the translation (C moves with -Rᵀ δt and not with δω at first
  // order), s² the residual variance per component (sum of squares / (2n - 6); both whitened when the points'
  // covariances are given). Without them it treats the points as exact, a lower bound on how well the camera is
  // placed. Valid when `covariance_valid`.
  Matrix3d centre_covariance = Matrix3d::Zero();
  // Covariance of the rotation (radians²) as a small rotation δω of the camera in its own frame, cam_from_world
  // becoming exp(δω) · cam_from_world: the same normal equations restricted to the rotation. Valid with it.
  Matrix3d rotation_covariance = Matrix3d::Zero();
  // Their cross-covariance E[δω δCᵀ] (radians · unit of the points): a camera that rests on points at one depth Z
  // trades a sideways shift of its centre against a turn (the bas-relief ambiguity), δω ≈ δC / Z about the axis
  // perpendicular to both, which this holds and the two blocks alone do not.
  Matrix3d rotation_centre_covariance = Matrix3d::Zero();
  bool covariance_valid = false;
  int num_iterations = 0;  // samples drawn
};

// Robust absolute pose from correspondences points_in_world[i] <-> bearings[i] (unit vectors in the camera
// frame). `focal_length_px` converts the pixel thresholds to angles (CameraModel::FocalLength()). Never
// throws; failures (too few correspondences or inliers, invalid input, no hypothesis) are reported in the
// result.
//
// `point_covariances` (optional, one per point): how uncertain each point is, in the unit of the points² per rad² of
// an image measurement's angular error — the points of a two-view reconstruction were measured by the same kind of
// observations as the bearings (TwoViewPointCovariance). The refinement then weighs each residual by its covariance
// σ² (I + J_X Σ_X J_Xᵀ), J_X its Jacobian in the point (the maximum-likelihood pose when the points are uncertain;
// Vakhitov et al. 2021, "Uncertainty-aware camera pose estimation from points and lines", take the same model), and
// the camera centre's covariance includes what the points' errors contribute. A point whose depth two close views
// hardly fix (near their epipole) then hardly moves the camera's position, though it still fixes its rotation.
// The robust sampling is unchanged; after it, a correspondence is an inlier when its whitened residual (its
// Mahalanobis distance) is within the threshold — a threshold on the plain residual keeps the points whose errors
// happen to agree with the sampled pose, and the estimate and its covariance then inherit that selection (in
// PointCovariancesWeighTheReconstructionsErrors of the tests: the centre's error 2.8 times larger). With
// `options.weigh_by_point_covariances` false the covariances enter the centre's and rotation's covariance only.
AbsolutePose EstimateAbsolutePose(const std::vector<Vector3d>& points_in_world, const std::vector<Vector3d>& bearings,
                                  double focal_length_px, const AbsolutePoseOptions& options = AbsolutePoseOptions(),
                                  const std::vector<Matrix3d>* point_covariances = nullptr);

}  // namespace retrace
