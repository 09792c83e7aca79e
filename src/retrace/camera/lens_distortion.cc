#include "retrace/camera/lens_distortion.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

namespace retrace {

Vector2d ApplyLensDistortion(const LensDistortion& d, const Vector2d& ideal) {
  if (d.IsZero()) return ideal;
  const double x = ideal.x(), y = ideal.y();
  const double r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (d.k1 + r2 * (d.k2 + r2 * d.k3));
  return Vector2d(x * radial + 2.0 * d.p1 * x * y + d.p2 * (r2 + 2.0 * x * x),
                  y * radial + d.p1 * (r2 + 2.0 * y * y) + 2.0 * d.p2 * x * y);
}

InverseRadialPolynomial FitInverseRadialPolynomial(const LensDistortion& d, double max_ideal_radius) {
  if (d.IsZero() || !(max_ideal_radius > 0.0)) return {0.0, 0.0, 0.0};
  const auto distorted_radius = [&d](double ru) {
    const double ru2 = ru * ru;
    return ru * (1.0 + ru2 * (d.k1 + ru2 * (d.k2 + ru2 * d.k3)));
  };
  // Stop the range where r_d(r_u) stops increasing: beyond, the radial map folds back and has no inverse.
  constexpr int kScan = 512;
  double max_radius = max_ideal_radius;
  double previous = 0.0;
  for (int i = 1; i <= kScan; ++i) {
    const double ru = max_ideal_radius * i / kScan;
    const double rd = distorted_radius(ru);
    if (rd <= previous) {
      max_radius = max_ideal_radius * (i - 1) / kScan;
      break;
    }
    previous = rd;
  }
  if (!(max_radius > 0.0)) return {0.0, 0.0, 0.0};
  // Least squares on samples (r_d, r_u): r_u / r_d - 1 = c1 r_d^2 + c2 r_d^4 + c3 r_d^6.
  constexpr int kSamples = 64;
  Eigen::MatrixXd a(kSamples, 3);
  Eigen::VectorXd b(kSamples);
  for (int i = 0; i < kSamples; ++i) {
    const double ru = max_radius * (i + 1) / kSamples;
    const double rd = distorted_radius(ru);
    const double rd2 = rd * rd;
    a.row(i) << rd2, rd2 * rd2, rd2 * rd2 * rd2;
    b(i) = ru / rd - 1.0;
  }
  const Eigen::Vector3d c = a.colPivHouseholderQr().solve(b);
  if (!c.allFinite()) return {0.0, 0.0, 0.0};
  return {c(0), c(1), c(2)};
}

bool RemoveLensDistortion(const LensDistortion& d, const InverseRadialPolynomial& c, const Vector2d& distorted,
                          Vector2d* ideal) {
  if (d.IsZero()) {
    *ideal = distorted;
    return true;
  }
  // Start from the fitted inverse radial polynomial ...
  const double rd2 = distorted.squaredNorm();
  Vector2d u = distorted * (1.0 + rd2 * (c[0] + rd2 * (c[1] + rd2 * c[2])));
  // ... and polish with Gauss-Newton on the forward model; two or three steps reach machine precision.
  constexpr double kTolerance2 = 1e-20;
  for (int iteration = 0; iteration < 20; ++iteration) {
    const double x = u.x(), y = u.y();
    const double r2 = x * x + y * y;
    const double radial = 1.0 + r2 * (d.k1 + r2 * (d.k2 + r2 * d.k3));
    const double dradial_dr2 = d.k1 + r2 * (2.0 * d.k2 + 3.0 * r2 * d.k3);
    const Vector2d residual = ApplyLensDistortion(d, u) - distorted;
    if (residual.squaredNorm() < kTolerance2 * std::max(1.0, distorted.squaredNorm())) break;
    Eigen::Matrix2d jacobian;
    jacobian(0, 0) = radial + 2.0 * x * x * dradial_dr2 + 2.0 * d.p1 * y + 6.0 * d.p2 * x;
    jacobian(0, 1) = 2.0 * x * y * dradial_dr2 + 2.0 * d.p1 * x + 2.0 * d.p2 * y;
    jacobian(1, 0) = jacobian(0, 1);
    jacobian(1, 1) = radial + 2.0 * y * y * dradial_dr2 + 6.0 * d.p1 * y + 2.0 * d.p2 * x;
    const double det = jacobian.determinant();
    if (!std::isfinite(det) || std::abs(det) < 1e-12) break;
    u -= jacobian.inverse() * residual;
  }
  *ideal = u;
  const Vector2d residual = ApplyLensDistortion(d, u) - distorted;
  return u.allFinite() && residual.squaredNorm() < kTolerance2 * std::max(1.0, distorted.squaredNorm());
}

}  // namespace retrace
