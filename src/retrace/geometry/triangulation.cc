#include "retrace/geometry/triangulation.h"

#include <cmath>

namespace retrace {

bool TriangulateMidpoint(const Rigid3d& b_from_a, const Vector3d& bearing_a, const Vector3d& bearing_b,
                         TriangulatedPoint* point) {
  // Rays in A's frame: X = λ_a d_a (from the origin) and X = c_b + λ_b d_b, with c_b the centre of B.
  const Matrix3d& r = b_from_a.rotation;
  const Vector3d c_b = -r.transpose() * b_from_a.translation;
  const Vector3d d_a = bearing_a.normalized();
  const Vector3d d_b = (r.transpose() * bearing_b).normalized();
  // Minimise |λ_a d_a - c_b - λ_b d_b|²: normal equations [1 -a; a -1] [λ_a; λ_b] = [d_a·c_b; d_b·c_b], a = d_a·d_b.
  const double a = d_a.dot(d_b);
  const double denom = 1.0 - a * a;
  if (!(denom > 1e-14)) return false;  // parallel rays (or NaN input)
  const double p = d_a.dot(c_b);
  const double q = d_b.dot(c_b);
  const double lambda_a = (p - a * q) / denom;
  const double lambda_b = (a * p - q) / denom;
  point->point_in_a = 0.5 * (lambda_a * d_a + c_b + lambda_b * d_b);
  point->depth_a = lambda_a;
  point->depth_b = lambda_b;
  return std::isfinite(lambda_a) && std::isfinite(lambda_b);
}

bool InFrontOfBothCameras(const Rigid3d& b_from_a, const Vector3d& bearing_a, const Vector3d& bearing_b) {
  TriangulatedPoint point;
  return TriangulateMidpoint(b_from_a, bearing_a, bearing_b, &point) && point.depth_a > 0.0 && point.depth_b > 0.0;
}

Matrix3d TwoViewPointCovariance(const Vector3d& point_in_a, const Vector3d& centre_b_in_a, double min_sin_parallax) {
  const Vector3d d_a = point_in_a.normalized();
  Vector3d d_b = (point_in_a - centre_b_in_a).normalized();
  // Keep the rays at least min_sin_parallax apart: turn B's ray away from A's about their common normal.
  const double sin_parallax = d_a.cross(d_b).norm();
  if (sin_parallax < min_sin_parallax) {
    Vector3d normal = d_a.cross(centre_b_in_a);
    if (normal.squaredNorm() < 1e-24) normal = d_a.cross(Vector3d::UnitX());
    if (normal.squaredNorm() < 1e-24) normal = d_a.cross(Vector3d::UnitY());
    d_b = Eigen::AngleAxisd(std::asin(min_sin_parallax), normal.normalized()) * d_a;
  }
  // B with A's orientation: x_b = x_a - c_b.
  const Rigid3d b_from_a(Matrix3d::Identity(), -centre_b_in_a);
  const double step = 1e-6;
  Matrix3d covariance = Matrix3d::Zero();
  for (const bool ray_a : {true, false}) {
    const Vector3d& ray = ray_a ? d_a : d_b;
    Vector3d u, v;
    TangentBasis(ray, &u, &v);
    for (const Vector3d& tangent : {u, v}) {
      TriangulatedPoint plus, minus;
      const Vector3d ray_plus = (ray + step * tangent).normalized(), ray_minus = (ray - step * tangent).normalized();
      if (!TriangulateMidpoint(b_from_a, ray_a ? ray_plus : d_a, ray_a ? d_b : ray_plus, &plus) ||
          !TriangulateMidpoint(b_from_a, ray_a ? ray_minus : d_a, ray_a ? d_b : ray_minus, &minus)) {
        continue;
      }
      const Vector3d jacobian = (plus.point_in_a - minus.point_in_a) / (2.0 * step);
      covariance += jacobian * jacobian.transpose();
    }
  }
  return covariance;
}

void TangentBasis(const Vector3d& bearing, Vector3d* u, Vector3d* v) {
  const Vector3d f = bearing.normalized();
  // u = normalize(e_y × f) is +x for f = +z; near the poles (f ∥ y) fall back to e_z × f... any orthogonal vector.
  Vector3d uu = Vector3d::UnitY().cross(f);
  if (uu.squaredNorm() < 1e-12) uu = f.cross(Vector3d::UnitZ());
  *u = uu.normalized();
  *v = f.cross(*u);
}

Vector2d TangentResidualPx(const Vector3d& bearing, const Vector3d& point_in_cam, double focal_length_px) {
  const double norm = point_in_cam.norm();
  if (!(norm > 0.0)) return Vector2d::Constant(focal_length_px);
  const Vector3d p = point_in_cam / norm;
  Vector3d u, v;
  TangentBasis(bearing, &u, &v);
  Vector2d residual(u.dot(p), v.dot(p));
  if (p.dot(bearing) < 0.0) {
    // Behind: the tangent component shrinks again past 90°; report at least one radian.
    const double n = residual.norm();
    residual = n > 1e-12 ? Vector2d(residual / n * (2.0 - n)) : Vector2d(2.0, 0.0);
  }
  return focal_length_px * residual;
}

}  // namespace retrace
