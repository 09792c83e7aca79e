#include "retrace/teach/planar_degeneracy.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <Eigen/SVD>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "retrace/geometry/essential.h"
#include "retrace/geometry/relative_pose.h"
#include "retrace/geometry/two_view_geometry.h"

namespace retrace {
namespace {

// Angle (radians) between the lines of two directions (sign ignored: a homography of bearings is defined up to
// scale, and its sign with it).
double LineAngle(const Vector3d& u, const Vector3d& v) {
  return std::atan2(u.cross(v).norm(), std::abs(u.dot(v)));
}

// H with f_B ∝ H f_A from the correspondences `indices` (direct linear transform, Hartley & Zisserman 2003 §4.1:
// the rows of [f_B]ₓ H f_A = 0). Bearings are unit vectors, which keeps the system well conditioned without the
// usual normalisation. False when the solution is degenerate.
bool FitHomography(const std::vector<Vector3d>& a, const std::vector<Vector3d>& b, const std::vector<int>& indices,
                   Matrix3d* h) {
  Eigen::Matrix<double, Eigen::Dynamic, 9> system(3 * indices.size(), 9);
  for (size_t row = 0; row < indices.size(); ++row) {
    const Vector3d& x = a[indices[row]];
    const Matrix3d cross = CrossProductMatrix(b[indices[row]]);
    // ([f_B]ₓ H f_A)_r = Σ_j cross(r, j) Σ_k H(j, k) x(k)
    for (int r = 0; r < 3; ++r) {
      for (int j = 0; j < 3; ++j) {
        for (int k = 0; k < 3; ++k) system(3 * row + r, 3 * j + k) = cross(r, j) * x(k);
      }
    }
  }
  const Eigen::JacobiSVD<Eigen::Matrix<double, Eigen::Dynamic, 9>> svd(system, Eigen::ComputeFullV);
  const Eigen::Matrix<double, 9, 1> solution = svd.matrixV().col(8);
  for (int j = 0; j < 3; ++j) {
    for (int k = 0; k < 3; ++k) (*h)(j, k) = solution(3 * j + k);
  }
  if (!h->allFinite()) return false;
  const Eigen::JacobiSVD<Matrix3d> singular(*h);
  return singular.singularValues()(2) > 1e-9 * singular.singularValues()(0);
}

// Squared distance (pixels²) of a correspondence to the homography in both images together: the symmetric transfer
// error over 4 (see the header).
double HomographyErrorSquared(const Matrix3d& h, const Matrix3d& h_inverse, const Vector3d& a, const Vector3d& b,
                              double focal) {
  const double forward = LineAngle(h * a, b), backward = LineAngle(h_inverse * b, a);
  return focal * focal * (forward * forward + backward * backward) / 4.0;
}

// Σ_i ρ(e_i² / σ²) + λ₁ d n + λ₂ k (Torr 1998).
double Gric(const std::vector<double>& squared_errors, double sigma, int manifold_dimension, int parameters) {
  constexpr double kDataDimension = 4.0, kLambda3 = 2.0;
  const double n = static_cast<double>(squared_errors.size());
  double sum = 0.0;
  for (const double e2 : squared_errors) {
    sum += std::min(e2 / (sigma * sigma), kLambda3 * (kDataDimension - manifold_dimension));
  }
  return sum + std::log(kDataDimension) * manifold_dimension * n + std::log(kDataDimension * n) * parameters;
}

// The MSAC cost (pixels²) of a motion over all correspondences, with the estimators' inlier rule (Sampson error
// below the threshold and in front of both cameras, two_view_geometry.h): Σ min(e², τ²); `inliers` receives them.
double MsacCost(const std::vector<Vector3d>& a, const std::vector<Vector3d>& b, const Rigid3d& b_from_a,
                double focal, double threshold_px, std::vector<int>* inliers) {
  TwoViewGeometry geometry;
  geometry.b_from_a = b_from_a;
  EvaluateTwoViewGeometry(a, b, focal, threshold_px, 0.05, &geometry);
  const Matrix3d essential = EssentialFromPose(b_from_a);
  const double tau2 = threshold_px * threshold_px;
  double cost = 0.0;
  inliers->clear();
  for (size_t i = 0; i < a.size(); ++i) {
    if (!geometry.inlier_mask[i]) {
      cost += tau2;
      continue;
    }
    inliers->push_back(static_cast<int>(i));
    cost += std::min(tau2, focal * focal * SampsonErrorSquared(essential, a[i], b[i]));
  }
  return cost;
}

// The motions b_from_a (unit translation) that the homography f_B ∝ H f_A decomposes into.
std::vector<Rigid3d> PlaneMotions(const Matrix3d& h) {
  cv::Mat homography, identity = cv::Mat::eye(3, 3, CV_64F);
  cv::eigen2cv(h, homography);
  std::vector<cv::Mat> rotations, translations, normals;
  std::vector<Rigid3d> motions;
  try {
    cv::decomposeHomographyMat(homography, identity, rotations, translations, normals);
  } catch (const cv::Exception&) {
    return motions;
  }
  for (size_t i = 0; i < rotations.size(); ++i) {
    Rigid3d motion;
    cv::cv2eigen(rotations[i], motion.rotation);
    Vector3d t;
    cv::cv2eigen(translations[i], t);
    if (!(t.norm() > 1e-12) || !motion.rotation.allFinite()) continue;
    motion.translation = t.normalized();
    motions.push_back(motion);
  }
  return motions;
}

}  // namespace

PlanarDegeneracy TestPlanarDegeneracy(const std::vector<Vector3d>& bearings_a, const std::vector<Vector3d>& bearings_b,
                                      const std::vector<bool>& inlier_mask, const Rigid3d& b_from_a,
                                      double focal_length_px, const PlanarDegeneracyOptions& options) {
  PlanarDegeneracy result;
  std::vector<Vector3d> a, b;
  for (size_t i = 0; i < bearings_a.size() && i < inlier_mask.size(); ++i) {
    if (!inlier_mask[i]) continue;
    a.push_back(bearings_a[i]);
    b.push_back(bearings_b[i]);
  }
  const int n = static_cast<int>(a.size());
  result.num_points = n;
  if (n < 4) {
    result.planar = true;  // not even a homography is determined
    return result;
  }

  // The motion's residuals, and the noise they show (Sampson error² / σ² is χ²(1), whose median is 0.4549).
  const Matrix3d essential = EssentialFromPose(b_from_a);
  const double focal2 = focal_length_px * focal_length_px;
  std::vector<double> essential_errors(n);
  for (int i = 0; i < n; ++i) essential_errors[i] = focal2 * SampsonErrorSquared(essential, a[i], b[i]);
  std::vector<double> sorted = essential_errors;
  std::nth_element(sorted.begin(), sorted.begin() + n / 2, sorted.end());
  constexpr double kMedianChiSquare1 = 0.4549364231195724;
  result.sigma_px = std::max(options.min_sigma_px, std::sqrt(sorted[n / 2] / kMedianChiSquare1));

  // The best homography over the motion's inliers: MSAC over random 4-samples, refined by the DLT on its inliers.
  const double tau2 = options.inlier_threshold_px * options.inlier_threshold_px;
  std::mt19937_64 random(options.seed);
  std::uniform_int_distribution<int> pick(0, n - 1);
  std::vector<double> best_errors;
  Matrix3d best_homography = Matrix3d::Zero();
  double best_cost = std::numeric_limits<double>::infinity();
  const auto evaluate = [&](const Matrix3d& h) {
    const Matrix3d h_inverse = h.inverse();
    std::vector<double> errors(n);
    double cost = 0.0;
    for (int i = 0; i < n; ++i) {
      errors[i] = HomographyErrorSquared(h, h_inverse, a[i], b[i], focal_length_px);
      cost += std::min(errors[i], tau2);
    }
    if (cost < best_cost) {
      best_cost = cost;
      best_homography = h;
      best_errors = std::move(errors);
      return true;
    }
    return false;
  };
  for (int s = 0; s < options.homography_samples; ++s) {
    std::vector<int> sample;
    while (sample.size() < 4) {
      const int i = pick(random);
      if (std::find(sample.begin(), sample.end(), i) == sample.end()) sample.push_back(i);
    }
    Matrix3d h;
    if (FitHomography(a, b, sample, &h)) evaluate(h);
  }
  for (int refinement = 0; refinement < 3 && !best_errors.empty(); ++refinement) {
    std::vector<int> inliers;
    for (int i = 0; i < n; ++i) {
      if (best_errors[i] < tau2) inliers.push_back(i);
    }
    Matrix3d h;
    if (inliers.size() < 4 || !FitHomography(a, b, inliers, &h) || !evaluate(h)) break;
  }
  if (best_errors.empty()) return result;  // no homography at all: not planar
  // Off the plane: a distance to the homography the noise explains with probability below 5 % (e² / σ² is χ² with
  // 2 degrees of freedom for points on it: 5.991 is its 95 % quantile).
  constexpr double kChiSquare2Quantile95 = 5.991464547107979;
  const double off_plane2 = kChiSquare2Quantile95 * result.sigma_px * result.sigma_px;
  result.homography_inliers = static_cast<int>(
      std::count_if(best_errors.begin(), best_errors.end(), [&](double e2) { return e2 <= off_plane2; }));

  // Torr 1998: the essential matrix has d = 3, k = 5; the homography d = 2, k = 8.
  result.gric_essential = Gric(essential_errors, result.sigma_px, 3, 5);
  result.gric_homography = Gric(best_errors, result.sigma_px, 2, 8);
  result.planar =
      result.gric_homography <= result.gric_essential || n - result.homography_inliers < kMinimalSample;

  // Another motion of the dominant plane that fits all correspondences alike (see the header).
  std::vector<int> inliers;
  const double estimate_cost = MsacCost(bearings_a, bearings_b, b_from_a, focal_length_px,
                                        options.inlier_threshold_px, &inliers);
  if (!(estimate_cost > 0)) return result;
  for (Rigid3d motion : PlaneMotions(best_homography)) {
    double cost = MsacCost(bearings_a, bearings_b, motion, focal_length_px, options.inlier_threshold_px, &inliers);
    for (int refinement = 0; refinement < 2 && inliers.size() >= static_cast<size_t>(kMinimalSample); ++refinement) {
      const Rigid3d refined = internal::RefineOnSampson(bearings_a, bearings_b, inliers, motion,
                                                        internal::GeneralPoseManifold(), 10);
      std::vector<int> refined_inliers;
      const double refined_cost =
          MsacCost(bearings_a, bearings_b, refined, focal_length_px, options.inlier_threshold_px, &refined_inliers);
      if (!(refined_cost < cost)) break;
      motion = refined;
      cost = refined_cost;
      inliers = std::move(refined_inliers);
    }
    const double rotation = RotationErrorDeg(motion.rotation, b_from_a.rotation);
    const double direction = AngleBetweenDeg(motion.translation, b_from_a.translation);
    if (rotation <= options.distinct_rotation_deg && direction <= options.distinct_direction_deg) continue;
    const double ratio = cost / estimate_cost;
    if (result.alternative_cost_ratio == 0.0 || ratio < result.alternative_cost_ratio) {
      result.alternative_cost_ratio = ratio;
      result.alternative_rotation_deg = rotation;
      result.alternative_direction_deg = direction;
    }
  }
  result.ambiguous = 2 * result.homography_inliers >= n && result.alternative_cost_ratio > 0.0 &&
                     result.alternative_cost_ratio <= 1.0 + options.preference;
  return result;
}

}  // namespace retrace
