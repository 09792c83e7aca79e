#include "retrace/camera/perspective_camera.h"

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

Vector2d PerspectiveCamera::Distort(const Vector2d& u) const {
  if (distortion_.IsZero()) return u;
  const LensDistortion& d = distortion_;
  const double x = u.x(), y = u.y();
  const double r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (d.k1 + r2 * (d.k2 + r2 * d.k3));
  return Vector2d(x * radial + 2.0 * d.p1 * x * y + d.p2 * (r2 + 2.0 * x * x),
                  y * radial + d.p1 * (r2 + 2.0 * y * y) + 2.0 * d.p2 * x * y);
}

Vector2d PerspectiveCamera::Undistort(const Vector2d& distorted) const {
  if (distortion_.IsZero()) return distorted;
  // Start from the fitted inverse radial polynomial (exact for the radial part up to the fit error) ...
  const double rd2 = distorted.squaredNorm();
  const auto& c = inverse_radial_;
  Vector2d u = distorted * (1.0 + rd2 * (c[0] + rd2 * (c[1] + rd2 * c[2])));
  // ... and polish with Gauss-Newton on the forward model; two or three steps reach machine precision.
  const LensDistortion& d = distortion_;
  for (int iteration = 0; iteration < 8; ++iteration) {
    const double x = u.x(), y = u.y();
    const double r2 = x * x + y * y;
    const double radial = 1.0 + r2 * (d.k1 + r2 * (d.k2 + r2 * d.k3));
    const double dradial_dr2 = d.k1 + r2 * (2.0 * d.k2 + 3.0 * r2 * d.k3);
    const Vector2d residual = Distort(u) - distorted;
    if (residual.squaredNorm() < 1e-24) break;
    Eigen::Matrix2d jacobian;
    jacobian(0, 0) = radial + 2.0 * x * x * dradial_dr2 + 2.0 * d.p1 * y + 6.0 * d.p2 * x;
    jacobian(0, 1) = 2.0 * x * y * dradial_dr2 + 2.0 * d.p1 * x + 2.0 * d.p2 * y;
    jacobian(1, 0) = 2.0 * x * y * dradial_dr2 + 2.0 * d.p1 * x + 2.0 * d.p2 * y;
    jacobian(1, 1) = radial + 2.0 * y * y * dradial_dr2 + 6.0 * d.p1 * y + 2.0 * d.p2 * x;
    u -= jacobian.inverse() * residual;
  }
  return u;
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
  *bearing = Undistort(PixelToNormalized(pixel)).homogeneous().normalized();
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
  inverse_radial_ = {0.0, 0.0, 0.0};
  if (distortion_.IsZero()) return;
  // Largest ideal radius the image can show: the farthest corner, in normalized coordinates.
  double max_radius = 0.0;
  for (const Vector2d corner : {Vector2d(0, 0), Vector2d(width_ - 1, 0), Vector2d(0, height_ - 1),
                                Vector2d(width_ - 1, height_ - 1)}) {
    max_radius = std::max(max_radius, PixelToNormalized(corner).norm());
  }
  // Least squares on samples (r_d, r_u) of the radial part: r_u / r_d - 1 = c1 r_d^2 + c2 r_d^4 + c3 r_d^6.
  constexpr int kSamples = 64;
  Eigen::MatrixXd a(kSamples, 3);
  Eigen::VectorXd b(kSamples);
  const LensDistortion& d = distortion_;
  for (int i = 0; i < kSamples; ++i) {
    const double ru = max_radius * (i + 1) / kSamples;
    const double ru2 = ru * ru;
    const double rd = ru * (1.0 + ru2 * (d.k1 + ru2 * (d.k2 + ru2 * d.k3)));
    const double rd2 = rd * rd;
    a.row(i) << rd2, rd2 * rd2, rd2 * rd2 * rd2;
    b(i) = rd != 0.0 ? ru / rd - 1.0 : 0.0;
  }
  const Eigen::Vector3d c = a.colPivHouseholderQr().solve(b);
  inverse_radial_ = {c(0), c(1), c(2)};
}

}  // namespace retrace
