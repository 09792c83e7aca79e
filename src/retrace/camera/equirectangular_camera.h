#pragma once

// Equirectangular panorama: the full sphere of directions on a width x height image (usually width = 2 height).
// Column u spans longitude -pi..pi (around the camera's y axis, 0 = straight ahead along +z, positive to the right,
// +x), row v spans latitude -pi/2 (up, -y) .. +pi/2 (down, +y). Every direction has a pixel, so Project() only fails
// at the centre of projection.

#include "retrace/camera/camera_model.h"

namespace retrace {

class EquirectangularCamera : public CameraModel {
 public:
  EquirectangularCamera(int width, int height);

  CameraModelType type() const override { return CameraModelType::kEquirectangular; }
  std::string model_name() const override { return "equirectangular"; }

  bool Project(const Vector3d& point_in_cam, Vector2d* pixel) const override;
  bool Unproject(const Vector2d& pixel, Vector3d* bearing) const override;
  // Pixels per radian of longitude.
  double FocalLength() const override { return width_ / (2.0 * M_PI); }
  std::unique_ptr<CameraModel> Scaled(double factor) const override;
  std::unique_ptr<CameraModel> Clone() const override;
};

}  // namespace retrace
