#include "retrace/camera/equirectangular_camera.h"

#include <cmath>

namespace retrace {

EquirectangularCamera::EquirectangularCamera(int width, int height) : CameraModel(width, height) {}

bool EquirectangularCamera::Project(const Vector3d& point_in_cam, Vector2d* pixel) const {
  const double norm = point_in_cam.norm();
  if (norm <= 0.0) return false;
  const double longitude = std::atan2(point_in_cam.x(), point_in_cam.z());
  const double latitude = std::asin(std::clamp(point_in_cam.y() / norm, -1.0, 1.0));
  // Pixel edges at 0 and width: the centre of column u is at longitude -pi + (u + 0.5) * 2 pi / width.
  pixel->x() = (longitude + M_PI) * width_ / (2.0 * M_PI) - 0.5;
  pixel->y() = (latitude + M_PI / 2.0) * height_ / M_PI - 0.5;
  return true;
}

bool EquirectangularCamera::Unproject(const Vector2d& pixel, Vector3d* bearing) const {
  const double longitude = (pixel.x() + 0.5) * 2.0 * M_PI / width_ - M_PI;
  const double latitude = (pixel.y() + 0.5) * M_PI / height_ - M_PI / 2.0;
  *bearing = Vector3d(std::cos(latitude) * std::sin(longitude), std::sin(latitude),
                      std::cos(latitude) * std::cos(longitude));
  return true;
}

std::unique_ptr<CameraModel> EquirectangularCamera::Scaled(double factor) const {
  return std::make_unique<EquirectangularCamera>(static_cast<int>(std::lround(width_ * factor)),
                                                 static_cast<int>(std::lround(height_ * factor)));
}

std::unique_ptr<CameraModel> EquirectangularCamera::Clone() const {
  return std::make_unique<EquirectangularCamera>(*this);
}

}  // namespace retrace
