#include "retrace/camera/unified_camera.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace retrace {

UnifiedCamera::UnifiedCamera(int width, int height, double xi, double fx, double fy, double cx, double cy,
                             double skew, const LensDistortion& distortion)
    : CameraModel(width, height), xi_(xi), fx_(fx), fy_(fy), cx_(cx), cy_(cy), skew_(skew), distortion_(distortion) {
  // Fit the inverse distortion over the normalized radii the image can show, limited to where lifting is defined
  // (1 + (1 - xi^2) r^2 >= 0).
  double max_radius = 0.0;
  for (const Vector2d& corner : {Vector2d(0, 0), Vector2d(width_ - 1, 0), Vector2d(0, height_ - 1),
                                Vector2d(width_ - 1, height_ - 1)}) {
    const double y = (corner.y() - cy_) / fy_;
    max_radius = std::max(max_radius, Vector2d((corner.x() - cx_ - skew_ * y) / fx_, y).norm());
  }
  if (xi_ > 1.0) max_radius = std::min(max_radius, 1.0 / std::sqrt(xi_ * xi_ - 1.0));
  inverse_radial_ = FitInverseRadialPolynomial(distortion_, max_radius);
}

bool UnifiedCamera::IsVisible(const Vector3d& bearing) const {
  const double norm = bearing.norm();
  if (!(norm > 0.0)) return false;
  const double limit = xi_ <= 1.0 ? -xi_ : -1.0 / xi_;
  return bearing.z() / norm > limit + 1e-9;
}

bool UnifiedCamera::Project(const Vector3d& point_in_cam, Vector2d* pixel) const {
  if (!IsVisible(point_in_cam)) return false;
  // Mei 2007, §III: onto the sphere, then through the centre shifted by xi.
  const Vector3d xs = point_in_cam.normalized();
  const double denominator = xs.z() + xi_;
  const Vector2d ideal(xs.x() / denominator, xs.y() / denominator);
  const Vector2d distorted = ApplyLensDistortion(distortion_, ideal);
  *pixel = Vector2d(fx_ * distorted.x() + skew_ * distorted.y() + cx_, fy_ * distorted.y() + cy_);
  return pixel->allFinite();
}

bool UnifiedCamera::Unproject(const Vector2d& pixel, Vector3d* bearing) const {
  const double yd = (pixel.y() - cy_) / fy_;
  const Vector2d distorted((pixel.x() - cx_ - skew_ * yd) / fx_, yd);
  Vector2d m;
  if (!RemoveLensDistortion(distortion_, inverse_radial_, distorted, &m)) return false;
  // Mei 2007, eq. (4): lift the normalized point back onto the unit sphere.
  const double r2 = m.squaredNorm();
  const double discriminant = 1.0 + (1.0 - xi_ * xi_) * r2;
  if (discriminant < 0.0) return false;
  const double factor = (xi_ + std::sqrt(discriminant)) / (r2 + 1.0);
  const Vector3d xs(factor * m.x(), factor * m.y(), factor - xi_);
  if (!IsVisible(xs)) return false;
  *bearing = xs.normalized();
  return true;
}

std::unique_ptr<CameraModel> UnifiedCamera::Scaled(double factor) const {
  // Pixel centres sit at integer coordinates, so scaling maps x to (x + 0.5) * factor - 0.5.
  const int width = static_cast<int>(std::lround(width_ * factor));
  const int height = static_cast<int>(std::lround(height_ * factor));
  return std::make_unique<UnifiedCamera>(width, height, xi_, fx_ * factor, fy_ * factor, (cx_ + 0.5) * factor - 0.5,
                                         (cy_ + 0.5) * factor - 0.5, skew_ * factor, distortion_);
}

std::unique_ptr<CameraModel> UnifiedCamera::Clone() const { return std::make_unique<UnifiedCamera>(*this); }

Matrix3d UnifiedCamera::K() const {
  Matrix3d k;
  k << fx_, skew_, cx_, 0.0, fy_, cy_, 0.0, 0.0, 1.0;
  return k;
}

}  // namespace retrace
