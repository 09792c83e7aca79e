#include "retrace/geometry/motion_uncertainty.h"

#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>
#include <boost/math/distributions/fisher_f.hpp>

#include "retrace/geometry/essential.h"
#include "retrace/geometry/relative_pose.h"
#include "retrace/geometry/triangulation.h"

namespace retrace {
namespace {

constexpr int kDim = 5;  // rotation and translation direction

std::vector<int> Inliers(const std::vector<Vector3d>& bearings_a, const std::vector<Vector3d>& bearings_b,
                         const std::vector<bool>& inlier_mask) {
  std::vector<int> inliers;
  for (size_t i = 0; i < bearings_a.size() && i < bearings_b.size() && i < inlier_mask.size(); ++i) {
    if (inlier_mask[i]) inliers.push_back(static_cast<int>(i));
  }
  return inliers;
}

// Σ r_i² of the Sampson residuals (radians) of `inliers`.
double SampsonCost(const std::vector<Vector3d>& bearings_a, const std::vector<Vector3d>& bearings_b,
                   const std::vector<int>& inliers, const Rigid3d& b_from_a) {
  const Matrix3d e = EssentialFromPose(b_from_a);
  double cost = 0.0;
  for (const int i : inliers) cost += SampsonErrorSquared(e, bearings_a[i], bearings_b[i]);
  return cost;
}

// d F⁻¹(c; d, n - 5): the region's bound on the cost increase in units of σ² (its radius squared, linearised).
double RegionBound(int d, int n, double confidence) {
  return d * boost::math::quantile(boost::math::fisher_f_distribution<double>(d, n - kDim), confidence);
}

}  // namespace

MotionUncertainty EstimateMotionUncertainty(const std::vector<Vector3d>& bearings_a,
                                            const std::vector<Vector3d>& bearings_b,
                                            const std::vector<bool>& inlier_mask, const Rigid3d& b_from_a,
                                            double focal_length_px, double confidence, double min_sigma_px) {
  constexpr double kInfinity = std::numeric_limits<double>::infinity();
  MotionUncertainty result;
  result.rotation_sigma_deg = result.direction_sigma_deg = kInfinity;
  result.rotation_bound_deg = result.direction_bound_deg = kInfinity;
  const std::vector<int> inliers = Inliers(bearings_a, bearings_b, inlier_mask);
  const int n = static_cast<int>(inliers.size());
  result.num_points = n;
  if (n <= kDim || !(focal_length_px > 0.0) || !(confidence > 0.0 && confidence < 1.0)) return result;

  const internal::PoseManifold manifold = internal::GeneralPoseManifold();
  const auto residuals = [&](const Rigid3d& pose, Eigen::VectorXd* r) {
    const Matrix3d e = EssentialFromPose(pose);
    r->resize(n);
    for (int k = 0; k < n; ++k) (*r)(k) = SampsonResidual(e, bearings_a[inliers[k]], bearings_b[inliers[k]]);
  };
  Eigen::VectorXd r;
  residuals(b_from_a, &r);
  const double min_sigma = min_sigma_px / focal_length_px;
  const double sigma = std::max(std::sqrt(r.squaredNorm() / (n - kDim)), min_sigma);
  result.sigma_px = sigma * focal_length_px;

  const Eigen::MatrixXd jacobian = internal::NumericJacobian(residuals, b_from_a, manifold, n);
  const Eigen::Matrix<double, kDim, kDim> normal = jacobian.transpose() * jacobian;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, kDim, kDim>> eigen(normal);
  if (eigen.info() != Eigen::Success || !(eigen.eigenvalues()(0) > 1e-12 * eigen.eigenvalues()(kDim - 1))) {
    return result;  // singular: some combination of the parameters is not observed at all
  }
  const Eigen::Matrix<double, kDim, kDim> covariance =
      sigma * sigma * eigen.eigenvectors() * eigen.eigenvalues().cwiseInverse().asDiagonal() *
      eigen.eigenvectors().transpose();
  const auto largest_sigma_deg = [](const Eigen::MatrixXd& block) {
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> block_eigen(block, Eigen::EigenvaluesOnly);
    return std::sqrt(std::max(block_eigen.eigenvalues().maxCoeff(), 0.0)) * 180.0 / M_PI;
  };
  result.rotation_sigma_deg = largest_sigma_deg(covariance.topLeftCorner<3, 3>());
  result.direction_sigma_deg = largest_sigma_deg(covariance.bottomRightCorner<2, 2>());
  result.rotation_bound_deg = std::sqrt(RegionBound(3, n, confidence)) * result.rotation_sigma_deg;
  result.direction_bound_deg = std::sqrt(RegionBound(2, n, confidence)) * result.direction_sigma_deg;
  return result;
}

DirectionTest TestDirectionAt(const std::vector<Vector3d>& bearings_a, const std::vector<Vector3d>& bearings_b,
                              const std::vector<bool>& inlier_mask, const Rigid3d& b_from_a, double focal_length_px,
                              double angle_deg, double confidence, double min_sigma_px) {
  DirectionTest result;
  result.within_region = true;
  const std::vector<int> inliers = Inliers(bearings_a, bearings_b, inlier_mask);
  const int n = static_cast<int>(inliers.size());
  if (n <= kDim || !(focal_length_px > 0.0) || !(confidence > 0.0 && confidence < 1.0)) return result;

  // The minimum S(θ̂): the estimate, refined on these inliers should it not be their optimum yet.
  constexpr int kIterations = 20;
  Rigid3d estimate = b_from_a;
  estimate.translation.normalize();
  const Rigid3d refined =
      internal::RefineOnSampson(bearings_a, bearings_b, inliers, estimate, internal::GeneralPoseManifold(), kIterations);
  double minimum = SampsonCost(bearings_a, bearings_b, inliers, estimate);
  if (const double cost = SampsonCost(bearings_a, bearings_b, inliers, refined); cost < minimum) {
    minimum = cost;
    estimate = refined;
  }
  const double min_sigma = min_sigma_px / focal_length_px;
  const double sigma2 = std::max(minimum / (n - kDim), min_sigma * min_sigma);
  result.bound = RegionBound(2, n, confidence);

  // The circle: t(φ) = cos α t̂ + sin α (cos φ b₁ + sin φ b₂); the profile cost is minimised over the rotation and φ.
  double alpha = angle_deg * M_PI / 180.0;  // the circle's radius (the lambdas below read it)
  const Vector3d center = estimate.translation;
  Vector3d b1, b2;
  TangentBasis(center, &b1, &b2);
  const auto on_circle = [&](double phi) {
    return Vector3d(std::cos(alpha) * center + std::sin(alpha) * (std::cos(phi) * b1 + std::sin(phi) * b2));
  };
  const internal::PoseManifold circle{4, [&](const Rigid3d& pose, const double* delta) {
                                        const double phi = std::atan2(pose.translation.dot(b2),
                                                                      pose.translation.dot(b1)) + delta[3];
                                        return Rigid3d(ExpSO3(Vector3d(delta[0], delta[1], delta[2])) * pose.rotation,
                                                       on_circle(phi));
                                      }};
  constexpr int kStarts = 8;
  double best = std::numeric_limits<double>::infinity();
  Rigid3d best_pose;
  for (int k = 0; k < kStarts; ++k) {
    const Rigid3d start(estimate.rotation, on_circle(2.0 * M_PI * k / kStarts));
    const Rigid3d profiled = internal::RefineOnSampson(bearings_a, bearings_b, inliers, start, circle, kIterations);
    const double cost = SampsonCost(bearings_a, bearings_b, inliers, profiled);
    if (cost < best) {
      best = cost;
      best_pose = profiled;
    }
  }
  result.direction = best_pose.translation;
  result.cost_increase = (best - minimum) / sigma2;
  result.within_region = result.cost_increase <= result.bound;
  if (!result.within_region) return result;

  // Connected: the circles at 1/4, 1/2 and 3/4 of the angle each hold a direction within the region, found by
  // continuing from the direction on the outer circle inwards.
  result.connected = true;
  const double outer = alpha;
  Rigid3d pose = best_pose;
  for (int k = 3; k >= 1 && result.connected; --k) {
    alpha = outer * k / 4.0;
    const double phi = std::atan2(pose.translation.dot(b2), pose.translation.dot(b1));
    pose = internal::RefineOnSampson(bearings_a, bearings_b, inliers, Rigid3d(pose.rotation, on_circle(phi)), circle,
                                     kIterations);
    result.connected = (SampsonCost(bearings_a, bearings_b, inliers, pose) - minimum) / sigma2 <= result.bound;
  }
  return result;
}

}  // namespace retrace
