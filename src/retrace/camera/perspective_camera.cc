#include "retrace/camera/perspective_camera.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

namespace retrace {

PerspectiveCamera::PerspectiveCamera(int width, int height, double fx, double fy, double cx, double cy)
    : PerspectiveCamera(width, height, fx, fy, cx, cy, 0.0, LensDistortion()) {}

PerspectiveCamera::PerspectiveCamera(int width, int height, double fx, double fy, double cx, double cy,
                                     double skew, const LensDistortion& distortion)
    : CameraModel(width, height), fx_(fx), fy_(fy), cx_(cx), cy_(cy), skew_(skew), distortion_(distortion) {
  FitInverseDistortion();
}

Vector2d PerspectiveCamera::NormalizedToPixel(const Vector2d& n) const {
  return Vector2d(fx_ * n.x() + skew_ * n.y() + cx_, fy_ * n.y() + cy_);
}

Vector2d PerspectiveCamera::PixelToNormalized(const Vector2d& p) const {
  const double y = (p.y() - cy_) / fy_;
  return Vector2d((p.x() - cx_ - skew_ * y) / fx_, y);
}

Vector2d PerspectiveCamera::Distort(const Vector2d& ideal) const { return ApplyLensDistortion(distortion_, ideal); }

Vector2d PerspectiveCamera::Undistort(const Vector2d& distorted) const {
  Vector2d ideal;
  RemoveLensDistortion(distortion_, inverse_radial_, distorted, &ideal);
  return ideal;
}

Vector2d PerspectiveCamera::DistortPixel(const Vector2d& ideal_pixel) const {
  return NormalizedToPixel(Distort(PixelToNormalized(ideal_pixel)));
}

Vector2d PerspectiveCamera::UndistortPixel(const Vector2d& distorted_pixel) const {
  return NormalizedToPixel(Undistort(PixelToNormalized(distorted_pixel)));
}

bool PerspectiveCamera::Project(const Vector3d& point_in_cam, Vector2d* pixel) const {
  if (point_in_cam.z() <= 1e-12 * point_in_cam.norm()) return false;
  *pixel = NormalizedToPixel(Distort(point_in_cam.hnormalized()));
  return true;
}

bool PerspectiveCamera::Unproject(const Vector2d& pixel, Vector3d* bearing) const {
  Vector2d ideal;
  if (!RemoveLensDistortion(distortion_, inverse_radial_, PixelToNormalized(pixel), &ideal)) return false;
  *bearing = ideal.homogeneous().normalized();
  return true;
}

std::unique_ptr<CameraModel> PerspectiveCamera::Scaled(double factor) const {
  // Pixel centres sit at integer coordinates, so scaling maps x to (x + 0.5) * factor - 0.5.
  const int width = static_cast<int>(std::lround(width_ * factor));
  const int height = static_cast<int>(std::lround(height_ * factor));
  return std::make_unique<PerspectiveCamera>(width, height, fx_ * factor, fy_ * factor, (cx_ + 0.5) * factor - 0.5,
                                             (cy_ + 0.5) * factor - 0.5, skew_ * factor, distortion_);
}

std::unique_ptr<CameraModel> PerspectiveCamera::Clone() const { return std::make_unique<PerspectiveCamera>(*this); }

Matrix3d PerspectiveCamera::K() const {
  Matrix3d k;
  k << fx_, skew_, cx_, 0.0, fy_, cy_, 0.0, 0.0, 1.0;
  return k;
}

void PerspectiveCamera::FitInverseDistortion() {
  // Largest radius the image can show: the farthest corner, in normalized coordinates.
  double max_radius = 0.0;
  for (const Vector2d& corner : {Vector2d(0, 0), Vector2d(width_ - 1, 0), Vector2d(0, height_ - 1),
                                Vector2d(width_ - 1, height_ - 1)}) {
    max_radius = std::max(max_radius, PixelToNormalized(corner).norm());
  }
  inverse_radial_ = FitInverseRadialPolynomial(distortion_, max_radius);
}

}  // namespace retrace
