#include "retrace/geometry/two_view_geometry.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <optional>
#include <random>

#include <Eigen/Cholesky>
#include <Eigen/SVD>

#include "retrace/geometry/essential.h"
#include "retrace/geometry/sigma_p.h"
#include "retrace/geometry/triangulation.h"

namespace retrace {

bool RansacOptions::Check() const {
  return max_error_px > 0.0 && confidence > 0.0 && confidence < 1.0 && min_iterations >= 0 &&
         max_iterations >= 1 && min_iterations <= max_iterations && min_iterations_with_guess >= 0 &&
         min_iterations_with_guess <= max_iterations;
}

bool TwoViewOptions::Check() const {
  return ransac.Check() && refinement_iterations >= 0 && min_inliers >= 5 && min_parallax_px >= 0.0 &&
         sigma_p_probability > 0.0 && sigma_p_probability < 1.0 && guess_preference >= 0.0;
}

const char* TwoViewFailureName(TwoViewFailure failure) {
  switch (failure) {
    case TwoViewFailure::kNone: return "none";
    case TwoViewFailure::kInvalidOptions: return "invalid options";
    case TwoViewFailure::kTooFewCorrespondences: return "too few correspondences";
    case TwoViewFailure::kInvalidInput: return "invalid input";
    case TwoViewFailure::kNoHypothesis: return "no hypothesis with the sample in front of both cameras";
    case TwoViewFailure::kTooFewInliers: return "too few inliers";
    case TwoViewFailure::kInsufficientParallax: return "insufficient parallax (pure rotation or no baseline)";
  }
  return "unknown";
}

namespace {

TwoViewGeometry Failure(TwoViewFailure failure, const std::string& detail, size_t num_correspondences) {
  TwoViewGeometry geometry;
  geometry.success = false;
  geometry.failure = failure;
  geometry.failure_message = std::string(TwoViewFailureName(failure)) + (detail.empty() ? "" : ": " + detail);
  geometry.inlier_mask.assign(num_correspondences, false);
  return geometry;
}

// Unit bearings with their tangent bases (TangentBasis), computed once for all the hypotheses scored on them.
struct BearingsWithBases {
  explicit BearingsWithBases(const std::vector<Vector3d>& bearings)
      : f(bearings), u(bearings.size()), v(bearings.size()) {
    for (size_t i = 0; i < f.size(); ++i) TangentBasis(f[i], &u[i], &v[i]);
  }
  Vector2d ResidualPx(size_t i, const Vector3d& point, double focal_length_px) const {
    return TangentResidualPx(f[i], u[i], v[i], point, focal_length_px);
  }
  const std::vector<Vector3d>& f;
  std::vector<Vector3d> u, v;
};

// Inlier test shared by scoring and evaluation: Sampson error below τ, triangulated (midpoint) in front of both
// cameras, and the triangulated point reprojects within τ (both images together). The last test rejects the
// occasional outlier that lies near its epipolar line but far from where the two rays meet. Returns the squared
// Sampson error (radians²) of an inlier, or a negative value for an outlier; fills `point` for inliers.
// (ua, va) and (ub, vb) are the tangent bases of fa and fb.
inline double InlierError(const Rigid3d& pose, const Matrix3d& e, const Vector3d& fa, const Vector3d& ua,
                          const Vector3d& va, const Vector3d& fb, const Vector3d& ub, const Vector3d& vb, double tau2,
                          TriangulatedPoint* point) {
  const double e2 = SampsonErrorSquared(e, fa, fb);
  if (!(e2 < tau2)) return -1.0;
  if (!TriangulateMidpoint(pose, fa, fb, point) || point->depth_a <= 0.0 || point->depth_b <= 0.0) return -1.0;
  const Vector2d residual_a = TangentResidualPx(fa, ua, va, point->point_in_a, 1.0);
  const Vector2d residual_b = TangentResidualPx(fb, ub, vb, pose * point->point_in_a, 1.0);
  if (!(residual_a.squaredNorm() + residual_b.squaredNorm() < tau2)) return -1.0;
  return e2;
}

// The same for correspondence i of two bearing lists.
inline double InlierError(const Rigid3d& pose, const Matrix3d& e, const BearingsWithBases& a,
                          const BearingsWithBases& b, size_t i, double tau2, TriangulatedPoint* point) {
  return InlierError(pose, e, a.f[i], a.u[i], a.v[i], b.f[i], b.u[i], b.v[i], tau2, point);
}

// MSAC cost of one correspondence and whether it is an inlier; τ² in radians².
inline double CorrespondenceCost(const Rigid3d& pose, const Matrix3d& e, const BearingsWithBases& a,
                                 const BearingsWithBases& b, size_t i, double tau2, bool* inlier) {
  TriangulatedPoint point;
  const double e2 = InlierError(pose, e, a, b, i, tau2, &point);
  *inlier = e2 >= 0.0;
  return *inlier ? e2 : tau2;
}

// MSAC cost of a pose over all correspondences, stopping early once it exceeds `bound`.
double ScorePose(const Rigid3d& pose, const BearingsWithBases& a, const BearingsWithBases& b, double tau2,
                 double bound, int* num_inliers) {
  const Matrix3d e = EssentialFromPose(pose);
  double cost = 0.0;
  int inliers = 0;
  for (size_t i = 0; i < a.f.size(); ++i) {
    bool inlier;
    cost += CorrespondenceCost(pose, e, a, b, i, tau2, &inlier);
    inliers += inlier;
    if (cost > bound) break;
  }
  *num_inliers = inliers;
  return cost;
}

std::vector<int> InlierIndices(const Rigid3d& pose, const BearingsWithBases& a, const BearingsWithBases& b,
                               double tau2) {
  const Matrix3d e = EssentialFromPose(pose);
  std::vector<int> indices;
  for (size_t i = 0; i < a.f.size(); ++i) {
    bool inlier;
    CorrespondenceCost(pose, e, a, b, i, tau2, &inlier);
    if (inlier) indices.push_back(static_cast<int>(i));
  }
  return indices;
}

// EvaluateTwoViewGeometry on bearings whose tangent bases are already computed (EstimateTwoView's, once for all its
// hypotheses).
void Evaluate(const BearingsWithBases& a, const BearingsWithBases& b, double focal_length_px, double max_error_px,
              double sigma_p_probability, TwoViewGeometry* geometry) {
  const std::vector<Vector3d>& bearings_a = a.f;
  const std::vector<Vector3d>& bearings_b = b.f;
  const size_t n = bearings_a.size();
  const Rigid3d& pose = geometry->b_from_a;
  const Matrix3d e = EssentialFromPose(pose);
  const double tau = max_error_px / focal_length_px;
  const double tau2 = tau * tau;
  geometry->inlier_mask.assign(n, false);
  geometry->points_in_a.assign(n, Vector3d::Zero());
  geometry->depths_a.assign(n, 0.0);
  geometry->depths_b.assign(n, 0.0);
  geometry->num_inliers = 0;
  double sum_squares = 0.0;
  std::vector<double> parallax;
  for (size_t i = 0; i < n; ++i) {
    TriangulatedPoint point;
    if (InlierError(pose, e, a, b, i, tau2, &point) < 0.0) continue;
    geometry->inlier_mask[i] = true;
    ++geometry->num_inliers;
    geometry->points_in_a[i] = point.point_in_a;
    geometry->depths_a[i] = point.depth_a;
    geometry->depths_b[i] = point.depth_b;
    // Residual measured in image B only (Segvic 2009 §4.5: 2n components), pixels.
    sum_squares += b.ResidualPx(i, pose * point.point_in_a, focal_length_px).squaredNorm();
  }
  // Parallax w.r.t. the best pure rotation of the inliers (not w.r.t. the estimated R: under pure rotation the
  // estimator can trade a little rotation for a fictitious translation and invent parallax). Rotation-only fit:
  // R_0 = argmin Σ |f_B - R f_A|² (Kabsch / Arun et al. 1987).
  Matrix3d correlation = Matrix3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    if (geometry->inlier_mask[i]) correlation += bearings_b[i] * bearings_a[i].transpose();
  }
  const Eigen::JacobiSVD<Matrix3d> svd(correlation, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Matrix3d sign = Matrix3d::Identity();
  sign(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  const Matrix3d rotation_only = svd.matrixU() * sign * svd.matrixV().transpose();
  for (size_t i = 0; i < n; ++i) {
    if (!geometry->inlier_mask[i]) continue;
    const Vector3d rotated = rotation_only * bearings_a[i];
    parallax.push_back(std::atan2(rotated.cross(bearings_b[i]).norm(), rotated.dot(bearings_b[i])) * focal_length_px);
  }
  const int m = geometry->num_inliers;
  geometry->sigma_p = SigmaPFromSumSquares(sum_squares, m, sigma_p_probability);
  geometry->rms_residual_px =
      m > 0 ? std::sqrt(sum_squares / (2.0 * m)) : std::numeric_limits<double>::infinity();
  if (!parallax.empty()) {
    auto mid = parallax.begin() + parallax.size() / 2;
    std::nth_element(parallax.begin(), mid, parallax.end());
    geometry->median_parallax_px = *mid;
  } else {
    geometry->median_parallax_px = 0.0;
  }
}

}  // namespace

bool IsInlierOfPose(const Rigid3d& b_from_a, const Vector3d& bearing_a, const Vector3d& bearing_b,
                    double focal_length_px, double max_error_px) {
  const double tau = max_error_px / focal_length_px;
  const Vector3d fa = bearing_a.normalized(), fb = bearing_b.normalized();
  Vector3d ua, va, ub, vb;
  TangentBasis(fa, &ua, &va);
  TangentBasis(fb, &ub, &vb);
  TriangulatedPoint point;
  return InlierError(b_from_a, EssentialFromPose(b_from_a), fa, ua, va, fb, ub, vb, tau * tau, &point) >= 0.0;
}

void EvaluateTwoViewGeometry(const std::vector<Vector3d>& bearings_a, const std::vector<Vector3d>& bearings_b,
                             double focal_length_px, double max_error_px, double sigma_p_probability,
                             TwoViewGeometry* geometry) {
  Evaluate(BearingsWithBases(bearings_a), BearingsWithBases(bearings_b), focal_length_px, max_error_px,
           sigma_p_probability, geometry);
}

namespace internal {

int RequiredIterations(double inlier_ratio, int sample_size, double confidence) {
  const double all_inliers = std::pow(inlier_ratio, sample_size);
  if (all_inliers >= 1.0 - 1e-12) return 0;
  if (all_inliers <= 1e-12) return std::numeric_limits<int>::max();
  const double n = std::log(1.0 - confidence) / std::log(1.0 - all_inliers);
  return n >= std::numeric_limits<int>::max() ? std::numeric_limits<int>::max() : static_cast<int>(std::ceil(n));
}

bool ValidBearings(const std::vector<Vector3d>& bearings) {
  for (const Vector3d& f : bearings) {
    if (!f.allFinite() || std::abs(f.squaredNorm() - 1.0) > 1e-6) return false;
  }
  return true;
}

Eigen::MatrixXd NumericJacobian(const PoseResiduals& residuals, const Rigid3d& pose, const PoseManifold& manifold,
                                int rows) {
  constexpr double kStep = 1e-7;
  Eigen::MatrixXd jacobian(rows, manifold.dim);
  std::vector<double> delta(manifold.dim, 0.0);
  Eigen::VectorXd plus, minus;
  for (int j = 0; j < manifold.dim; ++j) {
    std::fill(delta.begin(), delta.end(), 0.0);
    delta[j] = kStep;
    residuals(manifold.update(pose, delta.data()), &plus);
    delta[j] = -kStep;
    residuals(manifold.update(pose, delta.data()), &minus);
    jacobian.col(j) = (plus - minus) / (2.0 * kStep);
  }
  return jacobian;
}

Rigid3d RefineOnSampson(const std::vector<Vector3d>& bearings_a, const std::vector<Vector3d>& bearings_b,
                        const std::vector<int>& indices, const Rigid3d& initial, const PoseManifold& manifold,
                        int max_iterations, double cauchy_scale) {
  const int dim = manifold.dim;
  const int m = static_cast<int>(indices.size());
  if (m < dim || max_iterations <= 0) return initial;
  // Cauchy loss ρ(s) = c² log(1 + s / c²) on the squared Sampson residuals, minimised as weighted least squares
  // (iteratively reweighted: the weights are fixed during one LM step). A correspondence that passed the inlier
  // threshold by chance then pulls the pose much less than under a plain quadratic.
  const double c2 = cauchy_scale > 0.0 ? cauchy_scale * cauchy_scale : 0.0;
  Eigen::VectorXd weights = Eigen::VectorXd::Ones(m);
  auto residuals = [&](const Rigid3d& pose, Eigen::VectorXd* r) {
    const Matrix3d e = EssentialFromPose(pose);
    r->resize(m);
    for (int k = 0; k < m; ++k) {
      (*r)(k) = weights(k) * SampsonResidual(e, bearings_a[indices[k]], bearings_b[indices[k]]);
    }
  };
  auto update_weights = [&](const Rigid3d& pose) {
    if (c2 == 0.0) return;
    const Matrix3d e = EssentialFromPose(pose);
    for (int k = 0; k < m; ++k) {
      const double s = SampsonErrorSquared(e, bearings_a[indices[k]], bearings_b[indices[k]]);
      weights(k) = std::sqrt(1.0 / (1.0 + s / c2));  // sqrt of the IRLS weight ρ'(s)
    }
  };
  Rigid3d pose = initial;
  Eigen::VectorXd r;
  update_weights(pose);
  residuals(pose, &r);
  double cost = r.squaredNorm();
  double lambda = 1e-4;
  std::vector<double> delta(dim, 0.0);
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    if (iteration > 0 && c2 > 0.0) {
      update_weights(pose);
      residuals(pose, &r);
      cost = r.squaredNorm();
    }
    // 5 parameters at most, so the Jacobian costs a few residual evaluations.
    const Eigen::MatrixXd jacobian = NumericJacobian(residuals, pose, manifold, m);
    const Eigen::MatrixXd jtj = jacobian.transpose() * jacobian;
    const Eigen::VectorXd jtr = jacobian.transpose() * r;
    bool improved = false;
    for (int attempt = 0; attempt < 10 && !improved; ++attempt) {
      Eigen::MatrixXd a = jtj;
      a.diagonal() += lambda * (jtj.diagonal().array() + 1e-12).matrix();
      const Eigen::VectorXd step = a.ldlt().solve(-jtr);
      if (!step.allFinite()) break;
      for (int j = 0; j < dim; ++j) delta[j] = step(j);
      const Rigid3d candidate = manifold.update(pose, delta.data());
      Eigen::VectorXd r_candidate;
      residuals(candidate, &r_candidate);
      const double candidate_cost = r_candidate.squaredNorm();
      if (std::isfinite(candidate_cost) && candidate_cost < cost) {
        const double relative_decrease = (cost - candidate_cost) / std::max(cost, 1e-300);
        pose = candidate;
        r = r_candidate;
        cost = candidate_cost;
        lambda = std::max(lambda * 0.1, 1e-12);
        improved = true;
        if (relative_decrease < 1e-10 && c2 == 0.0) return pose;
      } else {
        lambda *= 10.0;
      }
    }
    if (!improved) break;
  }
  return pose;
}

TwoViewGeometry EstimateTwoView(const std::vector<Vector3d>& bearings_a, const std::vector<Vector3d>& bearings_b,
                                double focal_length_px, const TwoViewOptions& options, int sample_size,
                                const MinimalSolver& solver, const PoseManifold& manifold, const Rigid3d* guess) {
  const size_t n = bearings_a.size();
  if (!options.Check()) return Failure(TwoViewFailure::kInvalidOptions, "", n);
  if (bearings_b.size() != n) {
    return Failure(TwoViewFailure::kInvalidInput, "bearing lists of different sizes", std::max(n, bearings_b.size()));
  }
  if (!(focal_length_px > 0.0) || !std::isfinite(focal_length_px)) {
    return Failure(TwoViewFailure::kInvalidInput, "focal length must be positive", n);
  }
  if (!ValidBearings(bearings_a) || !ValidBearings(bearings_b)) {
    return Failure(TwoViewFailure::kInvalidInput, "bearings must be finite unit vectors", n);
  }
  const int min_needed = std::max(sample_size, options.min_inliers);
  if (static_cast<int>(n) < min_needed) {
    return Failure(TwoViewFailure::kTooFewCorrespondences,
                   std::to_string(n) + " < " + std::to_string(min_needed), n);
  }

  const double tau = options.ransac.max_error_px / focal_length_px;
  const double tau2 = tau * tau;
  const double min_separation2 = 0.01 * tau2;  // 0.1 τ apart at least
  const BearingsWithBases a(bearings_a), b(bearings_b);
  std::mt19937_64 rng(options.ransac.seed);
  std::vector<int> pool(n);
  std::iota(pool.begin(), pool.end(), 0);
  std::vector<int> sample(sample_size);
  std::vector<Rigid3d> candidates;

  Rigid3d best_pose;
  double best_cost = std::numeric_limits<double>::infinity();
  int required = options.ransac.max_iterations;
  int min_iterations = options.ransac.min_iterations;
  std::optional<Rigid3d> guess_pose;
  if (guess != nullptr && guess->rotation.allFinite() && guess->translation.allFinite() &&
      guess->translation.norm() > 0.0) {
    const Rigid3d pose(guess->rotation, guess->translation.normalized());
    guess_pose = pose;
    int inliers = 0;
    best_cost = ScorePose(pose, a, b, tau2, best_cost, &inliers);
    best_pose = pose;
    min_iterations = options.ransac.min_iterations_with_guess;
    required = std::max(min_iterations, RequiredIterations(static_cast<double>(inliers) / n, sample_size,
                                                           options.ransac.confidence));
  }
  int iteration = 0;
  for (; iteration < options.ransac.max_iterations && (iteration < min_iterations || iteration < required);
       ++iteration) {
    // Partial Fisher-Yates shuffle: the first sample_size entries of the pool are a uniform sample.
    for (int k = 0; k < sample_size; ++k) {
      std::uniform_int_distribution<int> pick(k, static_cast<int>(n) - 1);
      std::swap(pool[k], pool[pick(rng)]);
      sample[k] = pool[k];
    }
    // Degenerate sample: two correspondences on (nearly) the same ray in either image carry no information.
    bool distinct = true;
    for (int i = 0; i < sample_size && distinct; ++i) {
      for (int j = i + 1; j < sample_size; ++j) {
        if ((bearings_a[sample[i]] - bearings_a[sample[j]]).squaredNorm() < min_separation2 ||
            (bearings_b[sample[i]] - bearings_b[sample[j]]).squaredNorm() < min_separation2) {
          distinct = false;
          break;
        }
      }
    }
    if (!distinct) continue;
    candidates.clear();
    solver(sample, &candidates);
    for (const Rigid3d& pose : candidates) {
      if (!pose.rotation.allFinite() || !pose.translation.allFinite()) continue;
      int inliers = 0;
      const double cost = ScorePose(pose, a, b, tau2, best_cost, &inliers);
      if (cost < best_cost) {
        best_cost = cost;
        best_pose = pose;
        required = std::max(min_iterations, RequiredIterations(static_cast<double>(inliers) / n, sample_size,
                                                               options.ransac.confidence));
      }
    }
  }
  if (!std::isfinite(best_cost)) {
    TwoViewGeometry geometry = Failure(TwoViewFailure::kNoHypothesis, "", n);
    geometry.num_iterations = iteration;
    return geometry;
  }

  // Local optimisation: refine on the inliers, re-select, refine again while the inlier set grows.
  const auto optimise = [&](const Rigid3d& start) {
    Rigid3d pose = start;
    std::vector<int> inliers = InlierIndices(pose, a, b, tau2);
    for (int round = 0; round < 3 && static_cast<int>(inliers.size()) >= manifold.dim; ++round) {
      const Rigid3d refined = RefineOnSampson(bearings_a, bearings_b, inliers, pose, manifold,
                                              options.refinement_iterations);
      std::vector<int> refined_inliers = InlierIndices(refined, a, b, tau2);
      if (refined_inliers.size() < inliers.size()) break;
      pose = refined;
      const bool same = refined_inliers == inliers;
      inliers.swap(refined_inliers);
      if (same) break;
    }
    return pose;
  };
  Rigid3d pose = optimise(best_pose);
  // A sampled winner that fits barely better than the guess does not replace it (see
  // TwoViewOptions::guess_preference): both are refined and compared by their MSAC cost.
  if (guess_pose && options.guess_preference > 0.0) {
    const Rigid3d from_guess = optimise(*guess_pose);
    int unused = 0;
    const double cost = ScorePose(pose, a, b, tau2, std::numeric_limits<double>::infinity(), &unused);
    const double cost_guess =
        ScorePose(from_guess, a, b, tau2, std::numeric_limits<double>::infinity(), &unused);
    if (cost_guess <= (1.0 + options.guess_preference) * cost) pose = from_guess;
  }

  TwoViewGeometry geometry;
  geometry.b_from_a = pose;
  geometry.b_from_a.translation.normalize();
  geometry.num_iterations = iteration;
  Evaluate(a, b, focal_length_px, options.ransac.max_error_px, options.sigma_p_probability, &geometry);
  if (geometry.num_inliers < options.min_inliers) {
    const int found = geometry.num_inliers;
    TwoViewGeometry failure = Failure(TwoViewFailure::kTooFewInliers,
                                      std::to_string(found) + " < " + std::to_string(options.min_inliers), n);
    failure.num_iterations = iteration;
    return failure;
  }
  if (geometry.median_parallax_px < options.min_parallax_px) {
    char detail[96];
    std::snprintf(detail, sizeof(detail), "median %.2f px < %.2f px", geometry.median_parallax_px,
                  options.min_parallax_px);
    geometry.success = false;
    geometry.failure = TwoViewFailure::kInsufficientParallax;
    geometry.failure_message = std::string(TwoViewFailureName(geometry.failure)) + ": " + detail;
    return geometry;
  }
  geometry.success = true;
  return geometry;
}

}  // namespace internal
}  // namespace retrace
