#pragma once

// Unified central catadioptric / fisheye camera model (Mei & Rives, "Single View Point Omnidirectional Camera
// Calibration from Planar Grids", ICRA 2007), in the parameterisation of OpenCV's cv::omnidir module:
// xi, K = [fx s cx; 0 fy cy; 0 0 1] and radial-tangential distortion (k1, k2, p1, p2).
//
// Projection of a point X in the camera frame (Mei 2007, §III):
//   1. onto the unit sphere:               X_s = X / |X| = (x_s, y_s, z_s)
//   2. from a centre shifted by xi along z: m_u = (x_s / (z_s + xi), y_s / (z_s + xi))
//   3. lens distortion:                   m_d = D(m_u)  (plumb bob polynomial, lens_distortion.h)
//   4. pixels:                            p = K m_d
// xi = 0 is the pinhole camera, xi = 1 a parabolic mirror; fisheye lenses fit with xi around 1 and more.
// Lifting a pixel back to the sphere inverts steps 4..1; step 1 has the closed form (Mei 2007, eq. (4))
//   X_s = ((xi + sqrt(1 + (1 - xi^2) r^2)) / (r^2 + 1)) (m_x, m_y, 1) - (0, 0, xi),   r^2 = |m_u|^2.
// A direction has an image when z_s > -min(xi, 1/xi): for xi <= 1 the shifted centre must see it in front, for
// xi > 1 the rays beyond z_s = -1/xi would fold back onto pixels already used by other directions.

#include "retrace/camera/camera_model.h"
#include "retrace/camera/lens_distortion.h"

namespace retrace {

class UnifiedCamera : public CameraModel {
 public:
  // `distortion` uses k1, k2, p1, p2 (cv::omnidir); a non-zero k3 extends the radial polynomial the same way as in
  // the perspective model.
  UnifiedCamera(int width, int height, double xi, double fx, double fy, double cx, double cy, double skew = 0.0,
                const LensDistortion& distortion = LensDistortion());

  CameraModelType type() const override { return CameraModelType::kUnified; }
  std::string model_name() const override { return "unified"; }

  bool Project(const Vector3d& point_in_cam, Vector2d* pixel) const override;
  bool Unproject(const Vector2d& pixel, Vector3d* bearing) const override;
  // Near the axis a ray at angle theta lands at |m_u| = sin(theta) / (cos(theta) + xi) ~ theta / (1 + xi), so one
  // radian spans f / (1 + xi) pixels.
  double FocalLength() const override { return 0.5 * (fx_ + fy_) / (1.0 + xi_); }
  std::unique_ptr<CameraModel> Scaled(double factor) const override;
  std::unique_ptr<CameraModel> Clone() const override;

  // True when the direction `bearing` (any length > 0) has an image under this model (see the header comment).
  bool IsVisible(const Vector3d& bearing) const;

  double xi() const { return xi_; }
  double fx() const { return fx_; }
  double fy() const { return fy_; }
  double cx() const { return cx_; }
  double cy() const { return cy_; }
  double skew() const { return skew_; }
  const LensDistortion& distortion() const { return distortion_; }
  Matrix3d K() const;

 private:
  double xi_, fx_, fy_, cx_, cy_, skew_;
  LensDistortion distortion_;
  InverseRadialPolynomial inverse_radial_{0.0, 0.0, 0.0};
};

}  // namespace retrace
