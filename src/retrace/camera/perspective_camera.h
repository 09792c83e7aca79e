#pragma once

// Perspective camera: linear model K (fx, fy, skew, cx, cy) plus lens distortion in the OpenCV "plumb bob" form
// (radial k1, k2, k3 and tangential p1, p2), which covers the paper's radial model and the calibration files users
// have (OpenCV, ROS camera_info, EuRoC radial-tangential).
//
// Both directions are needed (Segvic 2009, §4.3): tracked points are undistorted before geometry, and predicted
// points are distorted before searching the image. Distortion is a closed-form polynomial; correction starts from a
// fitted inverse polynomial and polishes it with Gauss-Newton steps on the forward model, so both directions agree
// to far below 0.01 px inside the image.

#include "retrace/camera/camera_model.h"
#include "retrace/camera/lens_distortion.h"

namespace retrace {

class PerspectiveCamera : public CameraModel {
 public:
  // A pinhole camera without distortion.
  PerspectiveCamera(int width, int height, double fx, double fy, double cx, double cy);
  PerspectiveCamera(int width, int height, double fx, double fy, double cx, double cy, double skew,
                    const LensDistortion& distortion);

  CameraModelType type() const override { return CameraModelType::kPerspective; }
  std::string model_name() const override { return "perspective"; }

  bool Project(const Vector3d& point_in_cam, Vector2d* pixel) const override;
  bool Unproject(const Vector2d& pixel, Vector3d* bearing) const override;
  double FocalLength() const override { return 0.5 * (fx_ + fy_); }
  std::unique_ptr<CameraModel> Scaled(double factor) const override;
  std::unique_ptr<CameraModel> Clone() const override;

  // Normalized image coordinates (z = 1 plane) <-> pixels, without distortion.
  Vector2d NormalizedToPixel(const Vector2d& normalized) const;
  Vector2d PixelToNormalized(const Vector2d& pixel) const;

  // Lens distortion on normalized coordinates: Distort maps ideal to distorted, Undistort is its inverse (the last
  // Gauss-Newton iterate where the model is not invertible; Unproject() returns false there).
  Vector2d Distort(const Vector2d& ideal) const;
  Vector2d Undistort(const Vector2d& distorted) const;

  // Pixel-level helpers: the pixel where an ideal (undistorted) pixel is seen and back.
  Vector2d DistortPixel(const Vector2d& ideal_pixel) const;
  Vector2d UndistortPixel(const Vector2d& distorted_pixel) const;

  // The 3x3 calibration matrix K.
  Matrix3d K() const;

  double fx() const { return fx_; }
  double fy() const { return fy_; }
  double cx() const { return cx_; }
  double cy() const { return cy_; }
  double skew() const { return skew_; }
  const LensDistortion& distortion() const { return distortion_; }

 private:
  // Fits the coefficients of the inverse radial polynomial r_u = r_d (1 + c1 r_d^2 + c2 r_d^4 + c3 r_d^6) over the
  // radii inside the image; used as the starting point of Undistort().
  void FitInverseDistortion();

  double fx_, fy_, cx_, cy_, skew_;
  LensDistortion distortion_;
  InverseRadialPolynomial inverse_radial_{0.0, 0.0, 0.0};
};

}  // namespace retrace
