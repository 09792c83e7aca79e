#include "retrace/camera/camera_checks.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <vector>

#include <fmt/format.h>

#include "retrace/camera/perspective_camera.h"
#include "retrace/camera/unified_camera.h"

namespace retrace {
namespace {

constexpr double kDegreesPerRadian = 180.0 / M_PI;

double AngleBetweenDeg(const Vector3d& a, const Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * kDegreesPerRadian;
}

// `grid_size` x `grid_size` pixels spread over the whole image, corners included.
std::vector<Vector2d> PixelGrid(const CameraModel& camera, int grid_size) {
  const int n = std::max(grid_size, 2);
  std::vector<Vector2d> pixels;
  pixels.reserve(static_cast<size_t>(n) * n);
  for (int row = 0; row < n; ++row) {
    for (int col = 0; col < n; ++col) {
      pixels.emplace_back((camera.width() - 1) * col / (n - 1.0), (camera.height() - 1) * row / (n - 1.0));
    }
  }
  return pixels;
}

// The viewing angle swept along the line of pixels from `from` to `to`: the sum of the angles between the rays of
// consecutive pixels, so that a view wider than 180° adds up. Pixels without a ray (outside a fisheye's circle)
// are left out.
double FieldOfViewAlongDeg(const CameraModel& camera, const Vector2d& from, const Vector2d& to, int steps) {
  double sum = 0.0;
  bool has_previous = false;
  Vector3d previous = Vector3d::Zero();
  for (int i = 0; i <= steps; ++i) {
    const Vector2d pixel = from + (to - from) * (static_cast<double>(i) / steps);
    Vector3d ray;
    if (!camera.Unproject(pixel, &ray) || !ray.allFinite()) {
      has_previous = false;
      continue;
    }
    if (has_previous) sum += AngleBetweenDeg(previous, ray);
    previous = ray;
    has_previous = true;
  }
  return sum;
}

// Radial magnification dr_d/dr of the plumb-bob polynomial at ideal radius r (lens_distortion.h):
// r_d = r (1 + k1 r^2 + k2 r^4 + k3 r^6)  =>  dr_d/dr = 1 + 3 k1 r^2 + 5 k2 r^4 + 7 k3 r^6.
double RadialMagnification(const LensDistortion& d, double r) {
  const double r2 = r * r;
  return 1.0 + r2 * (3.0 * d.k1 + r2 * (5.0 * d.k2 + r2 * 7.0 * d.k3));
}

// The lens distortion of the model and the ideal normalized radius of a ray on it, for the models that have one.
struct DistortionView {
  const LensDistortion* distortion = nullptr;
  // Ideal (undistorted) normalized radius of a unit ray: perspective (x, y) / z, unified (x, y) / (z + xi).
  double IdealRadius(const Vector3d& ray) const {
    const double denominator = ray.z() + xi;
    return std::hypot(ray.x(), ray.y()) / denominator;
  }
  double xi = 0.0;
};

std::optional<DistortionView> DistortionOf(const CameraModel& camera) {
  if (const auto* perspective = dynamic_cast<const PerspectiveCamera*>(&camera)) {
    return DistortionView{&perspective->distortion(), 0.0};
  }
  if (const auto* unified = dynamic_cast<const UnifiedCamera*>(&camera)) {
    return DistortionView{&unified->distortion(), unified->xi()};
  }
  return std::nullopt;
}

}  // namespace

bool CheckCameraPlausible(const CameraModel& camera, std::string* problem, const CameraPlausibilityOptions& options) {
  const auto fail = [&](std::string text) {
    if (problem) *problem = std::move(text);
    return false;
  };
  const int width = camera.width();
  const int height = camera.height();
  if (width < 2 || height < 2) return fail(fmt::format("image size {}x{} is too small", width, height));

  // The optical axis must meet the image: a principal point outside it is a unit or sign mistake.
  Vector2d axis_pixel;
  if (!camera.Project(Vector3d(0, 0, 1), &axis_pixel) || !axis_pixel.allFinite() || !camera.InImage(axis_pixel)) {
    return fail(fmt::format("principal point ({:.1f}, {:.1f}) lies outside the {}x{} image ({})", axis_pixel.x(),
                            axis_pixel.y(), width, height, DescribeCameraIntrinsics(camera)));
  }

  const Vector2d centre(0.5 * (width - 1), 0.5 * (height - 1));
  const double horizontal = FieldOfViewAlongDeg(camera, {0.0, centre.y()}, {width - 1.0, centre.y()}, 64);
  const double vertical = FieldOfViewAlongDeg(camera, {centre.x(), 0.0}, {centre.x(), height - 1.0}, 64);
  if (!(std::min(horizontal, vertical) >= options.min_field_of_view_deg)) {
    return fail(fmt::format("field of view {:.2f}° x {:.2f}° is implausibly narrow (at least {}° expected; {})",
                            horizontal, vertical, options.min_field_of_view_deg, DescribeCameraIntrinsics(camera)));
  }

  // Both directions of the model must agree: every pixel's ray projects back onto it. A perspective image has a ray
  // at every pixel of its inscribed ellipse; the corners beyond may lie past where a fitted polynomial folds over
  // (real calibrations extrapolate badly there, e.g. OpenCV's sample stereo calibration), and an omnidirectional
  // model may leave everything outside its circle without a ray.
  const bool perspective = camera.type() == CameraModelType::kPerspective;
  const std::optional<DistortionView> lens = DistortionOf(camera);
  double min_magnification = 1.0, max_magnification = 1.0;
  int rays = 0;
  for (const Vector2d& pixel : PixelGrid(camera, options.grid_size)) {
    const Vector2d from_centre((pixel.x() - centre.x()) / (centre.x() + 0.5),
                               (pixel.y() - centre.y()) / (centre.y() + 0.5));
    const bool inscribed = from_centre.squaredNorm() <= 1.0;
    Vector3d ray;
    if (!camera.Unproject(pixel, &ray) || !ray.allFinite()) {
      if (perspective && inscribed) {
        return fail(fmt::format("the lens model has no ray for pixel ({:.0f}, {:.0f}): the distortion folds the image "
                                "over ({})",
                                pixel.x(), pixel.y(), DescribeCameraIntrinsics(camera)));
      }
      continue;
    }
    ++rays;
    Vector2d back;
    const bool projects = camera.Project(ray, &back) && back.allFinite();
    const double error = projects ? (back - pixel).norm() : std::numeric_limits<double>::infinity();
    if (!(error <= options.max_round_trip_error_px)) {
      return fail(fmt::format("the lens model does not map pixel ({:.0f}, {:.0f}) back onto itself ({:.2g} px off): "
                              "the distortion is not invertible over the image ({})",
                              pixel.x(), pixel.y(), error, DescribeCameraIntrinsics(camera)));
    }
    if (lens && inscribed) {
      const double magnification = RadialMagnification(*lens->distortion, lens->IdealRadius(ray));
      min_magnification = std::min(min_magnification, magnification);
      max_magnification = std::max(max_magnification, magnification);
    }
  }
  Vector3d centre_ray;
  if (rays == 0 || !camera.Unproject(centre, &centre_ray)) {
    return fail(fmt::format("the image centre has no ray ({})", DescribeCameraIntrinsics(camera)));
  }
  const double limit = options.max_distortion_magnification;
  if (!(max_magnification <= limit) || !(min_magnification > 0.0)) {
    return fail(fmt::format("the lens distortion magnifies the image {:.2g} to {:.2g} times across it (a real lens "
                            "stays between 0 and {}; {})",
                            min_magnification, max_magnification, limit, DescribeCameraIntrinsics(camera)));
  }
  return true;
}

double CameraProjectionDifferencePx(const CameraModel& a, const CameraModel& b, int grid_size) {
  double largest = 0.0;
  for (const Vector2d& pixel : PixelGrid(a, grid_size)) {
    Vector3d ray;
    if (!a.Unproject(pixel, &ray)) continue;
    Vector2d seen_by_b;
    if (!b.Project(ray, &seen_by_b) || !seen_by_b.allFinite()) return std::numeric_limits<double>::infinity();
    largest = std::max(largest, (seen_by_b - pixel).norm());
  }
  return largest;
}

std::string DescribeCameraIntrinsics(const CameraModel& camera) {
  const auto distortion_text = [](const LensDistortion& d) {
    if (d.IsZero()) return std::string();
    return fmt::format(" k1 {:.4g} k2 {:.4g} k3 {:.4g} p1 {:.4g} p2 {:.4g}", d.k1, d.k2, d.k3, d.p1, d.p2);
  };
  if (const auto* p = dynamic_cast<const PerspectiveCamera*>(&camera)) {
    return fmt::format("fx {:.6g} fy {:.6g} cx {:.6g} cy {:.6g}{}", p->fx(), p->fy(), p->cx(), p->cy(),
                       distortion_text(p->distortion()));
  }
  if (const auto* u = dynamic_cast<const UnifiedCamera*>(&camera)) {
    return fmt::format("xi {:.4g} fx {:.6g} fy {:.6g} cx {:.6g} cy {:.6g}{}", u->xi(), u->fx(), u->fy(), u->cx(),
                       u->cy(), distortion_text(u->distortion()));
  }
  return fmt::format("{} {}x{}", camera.model_name(), camera.width(), camera.height());
}

}  // namespace retrace
