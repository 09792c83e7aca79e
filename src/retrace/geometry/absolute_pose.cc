#include "retrace/geometry/absolute_pose.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include "retrace/geometry/essential.h"
#include "retrace/geometry/p3p.h"
#include "retrace/geometry/sigma_p.h"
#include "retrace/geometry/triangulation.h"

namespace retrace {
namespace {

// Squared residual of one correspondence: the squared norm of TangentResidualPx (radians), i.e. the squared
// sine of the angle between the bearing and the direction to the point, 1 - (f·p)² / |p|²; a point behind the
// camera along its ray costs 4 (more than one radian, so it never counts as an inlier).
double SquaredResidual(const Rigid3d& cam_from_world, const Vector3d& point, const Vector3d& bearing) {
  const Vector3d p = cam_from_world * point;
  const double along = bearing.dot(p);
  const double norm2 = p.squaredNorm();
  if (!(along > 0.0) || !(norm2 > 0.0)) return 4.0;
  return std::max(0.0, 1.0 - along * along / norm2);
}

// One correspondence under `pose`: the point in the camera `p`, the tangent-plane residual `r` (radians) of the
// direction to it against the bearing, its Jacobian in p, the residual's covariance C = I + J_X Σ_X J_Xᵀ per unit
// measurement variance (J_X = ∂r/∂p R) and its whitening W (WᵀW = C⁻¹); both the identity without Σ_X.
// False for a point at the camera's centre.
struct Correspondence {
  Vector3d p;
  Eigen::Vector2d r;
  Eigen::Matrix<double, 2, 3> d_r_d_p;
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Identity();
  Eigen::Matrix2d whitening = Eigen::Matrix2d::Identity();
};
bool Linearise(const Rigid3d& pose, const Vector3d& point, const Vector3d& bearing, const Matrix3d* point_covariance,
               Correspondence* c) {
  c->p = pose * point;
  const double norm = c->p.norm();
  if (!(norm > 0.0)) return false;
  const Vector3d direction = c->p / norm;
  Vector3d u, v;
  TangentBasis(bearing, &u, &v);
  c->r = Eigen::Vector2d(u.dot(direction), v.dot(direction));
  // d direction / d p = (I - d dᵀ) / |p|.
  c->d_r_d_p.row(0) = (u - u.dot(direction) * direction).transpose() / norm;
  c->d_r_d_p.row(1) = (v - v.dot(direction) * direction).transpose() / norm;
  c->covariance.setIdentity();
  c->whitening.setIdentity();
  if (point_covariance != nullptr) {
    const Eigen::Matrix<double, 2, 3> d_r_d_x = c->d_r_d_p * pose.rotation;
    c->covariance += d_r_d_x * *point_covariance * d_r_d_x.transpose();
    // C⁻¹ = L Lᵀ: W = Lᵀ.
    const Eigen::LLT<Eigen::Matrix2d> llt(c->covariance.inverse());
    if (llt.info() == Eigen::Success) c->whitening = llt.matrixU();
  }
  return true;
}

// The residual's Jacobian in the 6 parameters (δω, δt) of the update x_cam <- exp(δω) x_cam + δt:
// d p / d δω = -[p]ₓ, d p / d δt = I.
Eigen::Matrix<double, 2, 6> PoseJacobian(const Correspondence& c) {
  Eigen::Matrix<double, 2, 6> j;
  j.leftCols<3>() = -c.d_r_d_p * CrossProductMatrix(c.p);
  j.rightCols<3>() = c.d_r_d_p;
  return j;
}

// The correspondences within τ of `pose`: the residual's angle, or with `point_covariances` its whitened norm (the
// Mahalanobis distance in units of the measurement's σ: a point that two views placed badly may lie farther off).
std::vector<int> InlierIndices(const Rigid3d& pose, const std::vector<Vector3d>& points,
                               const std::vector<Vector3d>& bearings, const std::vector<Matrix3d>* point_covariances,
                               double tau2) {
  std::vector<int> inliers;
  for (size_t i = 0; i < points.size(); ++i) {
    const double e2 = SquaredResidual(pose, points[i], bearings[i]);
    bool inlier = e2 <= tau2;
    if (point_covariances != nullptr && e2 < 4.0) {
      Correspondence c;
      inlier = Linearise(pose, points[i], bearings[i], &(*point_covariances)[i], &c) &&
               (c.whitening * c.r).squaredNorm() <= tau2;
    }
    if (inlier) inliers.push_back(static_cast<int>(i));
  }
  return inliers;
}

// Squared sum of the (whitened) residuals of the correspondences `indices` under `pose`, and (when `jtj` is given)
// the normal equations of the 6 parameters (δω, δt) of the update x_cam <- exp(δω) x_cam + δt, i.e.
// R <- exp(δω) R, t <- exp(δω) t + δt.
double NormalEquations(const Rigid3d& pose, const std::vector<Vector3d>& points, const std::vector<Vector3d>& bearings,
                       const std::vector<int>& indices, const std::vector<Matrix3d>* point_covariances,
                       Eigen::Matrix<double, 6, 6>* jtj, Eigen::Matrix<double, 6, 1>* jtr) {
  double cost = 0.0;
  if (jtj != nullptr) {
    jtj->setZero();
    jtr->setZero();
  }
  for (const int i : indices) {
    Correspondence c;
    if (!Linearise(pose, points[i], bearings[i], point_covariances ? &(*point_covariances)[i] : nullptr, &c)) continue;
    const bool whiten = point_covariances != nullptr;  // else the whitening is the identity
    const Eigen::Vector2d r = whiten ? Eigen::Vector2d(c.whitening * c.r) : c.r;
    cost += r.squaredNorm();
    if (jtj == nullptr) continue;
    Eigen::Matrix<double, 2, 6> j = PoseJacobian(c);
    if (whiten) j = c.whitening * j;
    *jtj += j.transpose() * j;
    *jtr += j.transpose() * r;
  }
  return cost;
}

// B = Σ Jᵢᵀ Cᵢ Jᵢ over the correspondences `indices`: J the plain residual's Jacobian in the 6 parameters
// (PoseJacobian), C the residual's covariance per unit measurement variance (Linearise).
Eigen::Matrix<double, 6, 6> ResidualCovarianceNormalMatrix(const Rigid3d& pose, const std::vector<Vector3d>& points,
                                                           const std::vector<Vector3d>& bearings,
                                                           const std::vector<int>& indices,
                                                           const std::vector<Matrix3d>& point_covariances) {
  Eigen::Matrix<double, 6, 6> b = Eigen::Matrix<double, 6, 6>::Zero();
  for (const int i : indices) {
    Correspondence c;
    if (!Linearise(pose, points[i], bearings[i], &point_covariances[i], &c)) continue;
    const Eigen::Matrix<double, 2, 6> j = PoseJacobian(c);
    b += j.transpose() * c.covariance * j;
  }
  return b;
}

// Levenberg-Marquardt on the tangent-plane residuals of `indices` (whitened by the points' covariances when given)
// with the analytic Jacobian (least squares, as the two-view refinement: on a clean inlier set it is the
// maximum-likelihood estimate).
Rigid3d Refine(const std::vector<Vector3d>& points, const std::vector<Vector3d>& bearings,
               const std::vector<int>& indices, const std::vector<Matrix3d>* point_covariances, const Rigid3d& initial,
               int max_iterations) {
  Rigid3d pose = initial;
  Eigen::Matrix<double, 6, 6> jtj;
  Eigen::Matrix<double, 6, 1> jtr;
  double cost = NormalEquations(pose, points, bearings, indices, point_covariances, &jtj, &jtr);
  double lambda = 1e-4;
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    bool improved = false;
    for (int attempt = 0; attempt < 10 && !improved; ++attempt) {
      Eigen::Matrix<double, 6, 6> a = jtj;
      a.diagonal() += lambda * (jtj.diagonal().array() + 1e-12).matrix();
      const Eigen::Matrix<double, 6, 1> step = a.ldlt().solve(-jtr);
      if (!step.allFinite()) return pose;
      const Matrix3d rotation = ExpSO3(step.head<3>());
      const Rigid3d candidate(rotation * pose.rotation, rotation * pose.translation + step.tail<3>());
      const double candidate_cost =
          NormalEquations(candidate, points, bearings, indices, point_covariances, nullptr, nullptr);
      if (candidate_cost < cost) {
        const bool converged = cost - candidate_cost <= 1e-10 * cost;
        pose = candidate;
        lambda = std::max(lambda / 10.0, 1e-12);
        improved = true;
        cost = NormalEquations(pose, points, bearings, indices, point_covariances, &jtj, &jtr);
        if (converged) return pose;
      } else {
        lambda *= 10.0;
      }
    }
    if (!improved) break;
  }
  return pose;
}

AbsolutePose Failure(const std::string& message, size_t n) {
  AbsolutePose pose;
  pose.failure_message = message;
  pose.inlier_mask.assign(n, false);
  return pose;
}

}  // namespace

bool AbsolutePoseOptions::Check(std::string* error) const {
  const auto fail = [&](const char* message) {
    if (error != nullptr) *error = message;
    return false;
  };
  if (!ransac.Check()) return fail("invalid sampling options");
  if (min_inliers < 4) return fail("min_inliers must be >= 4");
  if (refinement_rounds < 0 || refinement_iterations < 0)
    return fail("refinement rounds and iterations must be >= 0");
  if (!(sigma_p_probability > 0 && sigma_p_probability < 1))
    return fail("sigma_p_probability must lie in (0, 1)");
  return true;
}

AbsolutePose EstimateAbsolutePose(const std::vector<Vector3d>& points_in_world, const std::vector<Vector3d>& bearings,
                                  double focal_length_px, const AbsolutePoseOptions& options,
                                  const std::vector<Matrix3d>* point_covariances) {
  const size_t n = points_in_world.size();
  constexpr int kSampleSize = 3;
  std::string error;
  if (!options.Check(&error)) return Failure("invalid options: " + error, n);
  if (bearings.size() != n)
    return Failure("points and bearings differ in number", std::max(n, bearings.size()));
  if (!(focal_length_px > 0.0) || !std::isfinite(focal_length_px))
    return Failure("focal length must be positive", n);
  if (!internal::ValidBearings(bearings)) return Failure("bearings must be finite unit vectors", n);
  for (const Vector3d& p : points_in_world) {
    if (!p.allFinite()) return Failure("points must be finite", n);
  }
  if (point_covariances != nullptr) {
    if (point_covariances->size() != n) return Failure("points and point covariances differ in number", n);
    for (const Matrix3d& c : *point_covariances) {
      if (!c.allFinite()) return Failure("point covariances must be finite", n);
    }
  }
  const int min_needed = std::max(kSampleSize + 1, options.min_inliers);
  if (static_cast<int>(n) < min_needed) {
    return Failure("too few correspondences: " + std::to_string(n) + " < " + std::to_string(min_needed), n);
  }

  const double tau = options.ransac.max_error_px / focal_length_px;
  const double tau2 = tau * tau;
  std::mt19937_64 rng(options.ransac.seed);
  std::vector<int> pool(n);
  std::iota(pool.begin(), pool.end(), 0);
  std::vector<int> sample(kSampleSize);
  std::vector<Rigid3d> solutions;
  solutions.reserve(4);

  Rigid3d best_pose;
  double best_cost = std::numeric_limits<double>::infinity();
  int required = options.ransac.max_iterations;
  int iteration = 0;
  for (; iteration < options.ransac.max_iterations &&
         (iteration < options.ransac.min_iterations || iteration < required);
       ++iteration) {
    for (int k = 0; k < kSampleSize; ++k) {
      std::uniform_int_distribution<int> pick(k, static_cast<int>(n) - 1);
      std::swap(pool[k], pool[pick(rng)]);
      sample[k] = pool[k];
    }
    const Vector3d sample_points[kSampleSize] = {points_in_world[sample[0]], points_in_world[sample[1]],
                                                 points_in_world[sample[2]]};
    const Vector3d sample_bearings[kSampleSize] = {bearings[sample[0]], bearings[sample[1]], bearings[sample[2]]};
    solutions.clear();
    SolveP3P(sample_points, sample_bearings, &solutions);
    for (const Rigid3d& pose : solutions) {
      double cost = 0.0;
      int inliers = 0;
      for (size_t i = 0; i < n && cost < best_cost; ++i) {
        const double e2 = SquaredResidual(pose, points_in_world[i], bearings[i]);
        inliers += e2 <= tau2;
        cost += std::min(e2, tau2);
      }
      if (cost < best_cost) {
        best_cost = cost;
        best_pose = pose;
        required = std::max(options.ransac.min_iterations,
                            internal::RequiredIterations(static_cast<double>(inliers) / n, kSampleSize,
                                                         options.ransac.confidence));
      }
    }
  }
  if (!std::isfinite(best_cost)) {
    AbsolutePose failure = Failure("no hypothesis", n);
    failure.num_iterations = iteration;
    return failure;
  }

  // Local optimisation: refine on the inliers, re-select, refine again while the inlier set grows.
  const std::vector<Matrix3d>* weighing = options.weigh_by_point_covariances ? point_covariances : nullptr;
  Rigid3d pose = best_pose;
  std::vector<int> inliers = InlierIndices(pose, points_in_world, bearings, weighing, tau2);
  for (int round = 0; round < options.refinement_rounds && static_cast<int>(inliers.size()) >= min_needed;
       ++round) {
    const Rigid3d refined = Refine(points_in_world, bearings, inliers, weighing, pose, options.refinement_iterations);
    std::vector<int> refined_inliers = InlierIndices(refined, points_in_world, bearings, weighing, tau2);
    if (refined_inliers.size() < inliers.size()) break;
    pose = refined;
    const bool same = refined_inliers == inliers;
    inliers.swap(refined_inliers);
    if (same) break;
  }

  AbsolutePose result;
  result.cam_from_world = pose;
  result.num_iterations = iteration;
  result.inlier_mask.assign(n, false);
  double sum_squares = 0.0;  // pixels²; whitened by the points' covariances when they weigh the residuals
  for (const int i : inliers) {
    result.inlier_mask[i] = true;
    if (weighing == nullptr) {
      sum_squares += TangentResidualPx(bearings[i], pose * points_in_world[i], focal_length_px).squaredNorm();
    } else {
      Correspondence c;
      if (Linearise(pose, points_in_world[i], bearings[i], &(*weighing)[i], &c)) {
        sum_squares += (focal_length_px * (c.whitening * c.r)).squaredNorm();
      }
    }
  }
  result.num_inliers = static_cast<int>(inliers.size());
  if (result.num_inliers < options.min_inliers) {
    result.failure_message = "too few inliers: " + std::to_string(result.num_inliers) + " < " +
                             std::to_string(options.min_inliers);
    return result;
  }
  result.sigma_p =
      SigmaPFromSumSquares(sum_squares, result.num_inliers, options.sigma_p_probability);  // eq. (6)
  result.rms_residual_px = std::sqrt(sum_squares / (2.0 * result.num_inliers));
  // Covariance of the camera centre from the normal equations at the solution (see AbsolutePose).
  if (result.num_inliers > 3) {
    Eigen::Matrix<double, 6, 6> jtj;
    Eigen::Matrix<double, 6, 1> jtr;
    // The unit variance from the whitened residuals; the estimate's normal matrix A: the whitened one, or the plain
    // one when the points were taken as exact and their errors enter the covariance only (the sandwich A⁻¹ B A⁻¹,
    // AbsolutePoseOptions::weigh_by_point_covariances).
    const bool sandwich = point_covariances != nullptr && weighing == nullptr;
    const double cost = NormalEquations(pose, points_in_world, bearings, inliers, point_covariances,
                                        sandwich ? nullptr : &jtj, &jtr);
    const double variance = cost / (2.0 * result.num_inliers - 6.0);
    if (sandwich) NormalEquations(pose, points_in_world, bearings, inliers, nullptr, &jtj, &jtr);
    const Eigen::FullPivLU<Eigen::Matrix<double, 6, 6>> lu(jtj);
    if (lu.isInvertible()) {
      const Eigen::Matrix<double, 6, 6> a_inverse = lu.inverse();
      const Eigen::Matrix<double, 6, 6> covariance =
          sandwich ? Eigen::Matrix<double, 6, 6>(
                         variance * a_inverse *
                         ResidualCovarianceNormalMatrix(pose, points_in_world, bearings, inliers, *point_covariances) *
                         a_inverse)
                   : Eigen::Matrix<double, 6, 6>(variance * a_inverse);
      const Matrix3d translation_covariance = covariance.bottomRightCorner<3, 3>();
      const Matrix3d& r = pose.rotation;
      result.centre_covariance = r.transpose() * translation_covariance * r;
      result.rotation_covariance = covariance.topLeftCorner<3, 3>();
      // δC = −Rᵀ δt (the left-multiplied update of Refine), so E[δω δCᵀ] = −E[δω δtᵀ] R.
      result.rotation_centre_covariance = -covariance.topRightCorner<3, 3>() * r;
      result.covariance_valid = result.centre_covariance.allFinite() && result.rotation_covariance.allFinite() &&
                                result.rotation_centre_covariance.allFinite();
    }
  }
  result.success = true;
  return result;
}

}  // namespace retrace
