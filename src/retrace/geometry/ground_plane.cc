#include "retrace/geometry/ground_plane.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

namespace retrace {
namespace {

constexpr double kDegree = M_PI / 180.0;

// Bilinear sample of a float image; false outside (one pixel of margin for the gradients).
bool Sample(const cv::Mat& image, double x, double y, double* value) {
  if (!(x >= 1 && y >= 1 && x < image.cols - 2 && y < image.rows - 2)) return false;
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const double fx = x - x0, fy = y - y0;
  const float* r0 = image.ptr<float>(y0) + x0;
  const float* r1 = image.ptr<float>(y0 + 1) + x0;
  *value = (1 - fy) * ((1 - fx) * r0[0] + fx * r0[1]) + fy * ((1 - fx) * r1[0] + fx * r1[1]);
  return true;
}

// One pyramid level: the images, their camera, and the region's samples in b.
struct Level {
  cv::Mat image_a, gradient_x, gradient_y;
  std::unique_ptr<CameraModel> camera;
  std::vector<Vector3d> bearings_b;  // unit bearings of the samples in camera b
  std::vector<double> intensities_b;
};

struct Residuals {
  std::vector<double> values;        // I_a(warp) - I_b, per sample inside a
  std::vector<Vector3d> jacobians;   // d residual / d m
  int total = 0;
};

// The photometric residuals of plane m = n / d (camera b's frame) and, when `jacobians`, their derivatives.
Residuals Evaluate(const Level& level, const Rigid3d& a_from_b, const Vector3d& m, bool jacobians) {
  Residuals out;
  out.total = static_cast<int>(level.bearings_b.size());
  out.values.reserve(level.bearings_b.size());
  if (jacobians) out.jacobians.reserve(level.bearings_b.size());
  for (size_t i = 0; i < level.bearings_b.size(); ++i) {
    const Vector3d& f = level.bearings_b[i];
    const double mf = m.dot(f);
    if (!(mf > 1e-9)) continue;  // the ray does not meet the plane in front of b
    // X_b = f / (mᵀf); in a: R X_b + t, scaled by mᵀf (a projection ignores the scale, as long as it is positive).
    const Vector3d x = a_from_b.rotation * f + mf * a_from_b.translation;
    Vector2d pixel;
    if (!level.camera->Project(x, &pixel)) continue;
    double value;
    if (!Sample(level.image_a, pixel.x(), pixel.y(), &value)) continue;
    if (jacobians) {
      // d pixel / d x by central differences (any camera model), then d x / d m = t fᵀ.
      Eigen::Matrix<double, 2, 3> projection_jacobian;
      bool ok = true;
      const double step = 1e-6 * x.norm();
      for (int k = 0; k < 3 && ok; ++k) {
        Vector3d plus = x, minus = x;
        plus(k) += step;
        minus(k) -= step;
        Vector2d p_plus, p_minus;
        ok = level.camera->Project(plus, &p_plus) && level.camera->Project(minus, &p_minus);
        projection_jacobian.col(k) = (p_plus - p_minus) / (2 * step);
      }
      double gx, gy;
      if (!ok || !Sample(level.gradient_x, pixel.x(), pixel.y(), &gx) ||
          !Sample(level.gradient_y, pixel.x(), pixel.y(), &gy)) {
        continue;
      }
      const double along_t = Vector2d(gx, gy).dot(projection_jacobian * a_from_b.translation);
      out.jacobians.push_back(along_t * f);
    }
    out.values.push_back(value - level.intensities_b[i]);
  }
  return out;
}

double RobustSigma(std::vector<double> values) {
  if (values.empty()) return 0.0;
  for (double& v : values) v = std::abs(v);
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return std::max(1.4826 * values[values.size() / 2], 0.5);
}

double HuberWeight(double residual, double threshold) {
  const double a = std::abs(residual);
  return a <= threshold ? 1.0 : threshold / a;
}

}  // namespace

bool GroundPlaneOptions::Check(std::string* error) const {
  const auto fail = [error](const std::string& message) {
    if (error != nullptr) *error = message;
    return false;
  };
  if (!(0 <= roi_top && roi_top < roi_bottom && roi_bottom <= 1 && 0 <= roi_left && roi_left < roi_right &&
        roi_right <= 1)) {
    return fail(fmt::format("the region of interest [{}, {}] x [{}, {}] is not inside the image", roi_left,
                            roi_right, roi_top, roi_bottom));
  }
  if (levels < 1 || levels > 6) return fail(fmt::format("levels must be in 1..6, got {}", levels));
  if (iterations < 1 || iterations > 100) return fail(fmt::format("iterations must be in 1..100, got {}", iterations));
  if (!(huber_sigmas > 0)) return fail(fmt::format("huber_sigmas must be > 0, got {}", huber_sigmas));
  if (!(max_tilt_deg > 0 && max_tilt_deg < 90)) {
    return fail(fmt::format("max_tilt_deg must be in (0, 90), got {}", max_tilt_deg));
  }
  if (!(min_distance > 0 && max_distance > min_distance)) {
    return fail(fmt::format("need 0 < min_distance < max_distance, got {} and {}", min_distance, max_distance));
  }
  if (search_steps < 2) return fail(fmt::format("search_steps must be at least 2, got {}", search_steps));
  if (!(min_overlap > 0 && min_overlap <= 1)) return fail(fmt::format("min_overlap must be in (0, 1], got {}", min_overlap));
  if (!(max_rms_residual > 0)) return fail(fmt::format("max_rms_residual must be > 0, got {}", max_rms_residual));
  if (!(max_relative_sigma > 0)) return fail(fmt::format("max_relative_sigma must be > 0, got {}", max_relative_sigma));
  return true;
}

GroundPlane EstimateGroundPlane(const cv::Mat& image_a, const cv::Mat& image_b, const CameraModel& camera,
                                const Rigid3d& b_from_a, const GroundPlaneOptions& options) {
  GroundPlane result;
  if (image_a.empty() || image_b.empty() || image_a.size() != image_b.size() || image_a.type() != CV_8UC1 ||
      image_b.type() != CV_8UC1) {
    return result;
  }
  const Rigid3d a_from_b = b_from_a.Inverse();

  // Pyramids (cv::pyrDown: level l has the pixel coordinates of level 0 divided by 2^l) and the region's samples,
  // at most ~6000 per level.
  std::vector<Level> levels(options.levels);
  cv::Mat a, b;
  image_a.convertTo(a, CV_32F);
  image_b.convertTo(b, CV_32F);
  for (int l = 0; l < options.levels; ++l) {
    if (l > 0) {
      cv::pyrDown(a, a);
      cv::pyrDown(b, b);
    }
    Level& level = levels[l];
    level.image_a = a;
    cv::Sobel(a, level.gradient_x, CV_32F, 1, 0, 3, 1.0 / 8);
    cv::Sobel(a, level.gradient_y, CV_32F, 0, 1, 3, 1.0 / 8);
    level.camera = camera.Scaled(1.0 / (1 << l));
    const int x0 = static_cast<int>(options.roi_left * b.cols), x1 = static_cast<int>(options.roi_right * b.cols);
    const int y0 = static_cast<int>(options.roi_top * b.rows), y1 = static_cast<int>(options.roi_bottom * b.rows);
    const double area = std::max(1, (x1 - x0) * (y1 - y0));
    const int stride = std::max(1, static_cast<int>(std::round(std::sqrt(area / 6000.0))));
    for (int y = y0; y < y1; y += stride) {
      for (int x = x0; x < x1; x += stride) {
        Vector3d bearing;
        if (!level.camera->Unproject(Vector2d(x, y), &bearing)) continue;
        level.bearings_b.push_back(bearing.normalized());
        level.intensities_b.push_back(b.at<float>(y, x));
      }
    }
  }

  // Start: the plane under camera b with n = the known normal or its down axis, d from a search at the coarsest
  // level.
  const Level& coarsest = levels.back();
  const Vector3d down = options.normal_in_camera ? options.normal_in_camera->normalized() : Vector3d::UnitY();
  Vector3d m = down / options.min_distance;
  double best_cost = std::numeric_limits<double>::infinity();
  for (int s = 0; s < options.search_steps; ++s) {
    const double d = options.min_distance *
                     std::pow(options.max_distance / options.min_distance, s / (options.search_steps - 1.0));
    const Residuals r = Evaluate(coarsest, a_from_b, down / d, false);
    if (r.values.size() < options.min_overlap * r.total) continue;
    const double cost = RobustSigma(r.values);
    if (cost < best_cost) {
      best_cost = cost;
      m = down / d;
    }
  }
  if (!std::isfinite(best_cost)) return result;

  // Gauss-Newton with Huber weights, coarse to fine.
  Matrix3d normal_matrix = Matrix3d::Zero();
  double sigma = 0.0;
  Residuals final_residuals;
  for (int l = options.levels - 1; l >= 0; --l) {
    for (int iteration = 0; iteration < options.iterations; ++iteration) {
      const Residuals r = Evaluate(levels[l], a_from_b, m, true);
      if (r.values.size() < options.min_overlap * r.total || r.values.size() < 20) return result;
      sigma = RobustSigma(r.values);
      normal_matrix.setZero();
      Vector3d gradient = Vector3d::Zero();
      for (size_t i = 0; i < r.values.size(); ++i) {
        const double w = HuberWeight(r.values[i], options.huber_sigmas * sigma);
        normal_matrix += w * r.jacobians[i] * r.jacobians[i].transpose();
        gradient += w * r.values[i] * r.jacobians[i];
      }
      // A small damping keeps the step bounded where the road's texture constrains m weakly. With a known normal,
      // m = s n and only s = 1 / d moves.
      Vector3d step;
      if (options.normal_in_camera) {
        const double curvature = down.dot(normal_matrix * down) * (1.0 + 1e-3);
        step = curvature > 0 ? Vector3d(-down.dot(gradient) / curvature * down) : Vector3d::Zero();
      } else {
        Matrix3d damped = normal_matrix;
        damped.diagonal() *= 1.0 + 1e-3;
        step = -damped.ldlt().solve(gradient);
      }
      if (!step.allFinite()) return result;
      m += step;
      if (step.norm() < 1e-4 * m.norm()) break;
    }
    if (l == 0) final_residuals = Evaluate(levels[0], a_from_b, m, false);
  }

  // The plane in b's frame, then in a's: n_aᵀ X_a = d_b - n_bᵀ t_ba with n_a = R_baᵀ n_b.
  const double norm = m.norm();
  if (!(norm > 0) || !std::isfinite(norm)) return result;
  const Vector3d normal_b = m / norm;
  const double distance_b = 1.0 / norm;
  const Vector3d normal_a = b_from_a.rotation.transpose() * normal_b;
  const double distance_a = distance_b - normal_b.dot(b_from_a.translation);
  // σ of d_b = 1 / |m| from the covariance of m (σ² (JᵀWJ)⁻¹); d_a differs from it by a known offset.
  const Vector3d d_by_m = -m / (norm * norm * norm);
  double distance_variance;
  if (options.normal_in_camera) {
    const double curvature = down.dot(normal_matrix * down);
    distance_variance = sigma * sigma / curvature * std::pow(d_by_m.dot(down), 2);
  } else {
    distance_variance = d_by_m.dot(sigma * sigma * normal_matrix.inverse() * d_by_m);
  }

  result.normal = normal_a;
  result.distance = distance_a;
  result.normal_b = normal_b;
  result.distance_b = distance_b;
  // A region without texture leaves m unconstrained (singular normal equations): no answer.
  if (!(distance_variance > 0) || !std::isfinite(distance_variance)) return result;
  result.distance_sigma = std::sqrt(distance_variance);
  result.overlap = final_residuals.total > 0 ? final_residuals.values.size() / double(final_residuals.total) : 0;
  {
    double squares = 0.0;
    int inliers = 0;
    for (double v : final_residuals.values) {
      if (std::abs(v) <= options.huber_sigmas * sigma) {
        squares += v * v;
        ++inliers;
      }
    }
    result.rms_residual = inliers > 0 ? std::sqrt(squares / inliers) : std::numeric_limits<double>::infinity();
  }
  const double min_cos = std::cos(options.max_tilt_deg * kDegree);
  result.valid = distance_a > 0 && distance_b > 0 && normal_a.y() >= min_cos && normal_b.y() >= min_cos &&
                 result.overlap >= options.min_overlap && result.rms_residual <= options.max_rms_residual &&
                 result.distance_sigma <= options.max_relative_sigma * distance_b;
  return result;
}

std::optional<Vector3d> CommonGroundNormal(const std::vector<GroundPlane>& planes, int min_planes) {
  std::array<std::vector<double>, 3> components;
  for (const GroundPlane& plane : planes) {
    if (!plane.valid) continue;
    for (int k = 0; k < 3; ++k) components[k].push_back(plane.normal_b(k));
  }
  if (static_cast<int>(components[0].size()) < std::max(1, min_planes)) return std::nullopt;
  Vector3d median;
  for (int k = 0; k < 3; ++k) {
    auto& c = components[k];
    std::nth_element(c.begin(), c.begin() + c.size() / 2, c.end());
    median(k) = c[c.size() / 2];
  }
  if (!(median.norm() > 0)) return std::nullopt;
  return median.normalized();
}

}  // namespace retrace
