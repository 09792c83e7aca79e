#include "retrace/geometry/triangulation.h"

#include <cmath>
#include <limits>

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
  Vector3d u, v;
  TangentBasis(bearing, &u, &v);
  return TangentResidualPx(bearing, u, v, point_in_cam, focal_length_px);
}

Vector2d TangentResidualPx(const Vector3d& bearing, const Vector3d& u, const Vector3d& v, const Vector3d& point_in_cam,
                           double focal_length_px) {
  const double norm = point_in_cam.norm();
  if (!(norm > 0.0)) return Vector2d::Constant(focal_length_px);
  const Vector3d p = point_in_cam / norm;
  Vector2d residual(u.dot(p), v.dot(p));
  if (p.dot(bearing) < 0.0) {
    // Behind: the tangent component shrinks again past 90°; report at least one radian.
    const double n = residual.norm();
    residual = n > 1e-12 ? Vector2d(residual / n * (2.0 - n)) : Vector2d(2.0, 0.0);
  }
  return focal_length_px * residual;
}

bool RefinePointMultiView(const std::vector<Rigid3d>& cam_from_world, const std::vector<Vector3d>& bearings,
                          const Vector3d& initial, double focal_length_px, Vector3d* point, double* max_residual_px) {
  const size_t views = cam_from_world.size();
  if (views < 2 || bearings.size() != views || !(focal_length_px > 0.0)) return false;
  // Residuals in a tangent basis fixed per view (the bearing's), so that the Jacobian is that of a smooth function:
  // r_i(X) = f [u_i · y, v_i · y], y = (R_i X + t_i) / |R_i X + t_i|; dy/dY = (I - y yᵀ) / |Y|, dY/dX = R_i.
  std::vector<std::pair<Vector3d, Vector3d>> bases(views);
  for (size_t i = 0; i < views; ++i) TangentBasis(bearings[i], &bases[i].first, &bases[i].second);
  const auto tangent_residual = [&](size_t i, const Vector3d& y) {
    return TangentResidualPx(bearings[i], bases[i].first, bases[i].second, y, focal_length_px);
  };
  // The sum of squared residuals (TangentResidualPx); infinite behind a camera.
  const auto cost = [&](const Vector3d& x) {
    double sum = 0.0;
    for (size_t i = 0; i < views; ++i) {
      const Vector3d y = cam_from_world[i].rotation * x + cam_from_world[i].translation;
      if (!(y.dot(bearings[i]) > 0.0)) return std::numeric_limits<double>::infinity();
      sum += tangent_residual(i, y).squaredNorm();
    }
    return sum;
  };
  Vector3d x = initial;
  double current = cost(x);
  if (!std::isfinite(current)) return false;
  double damping = 1e-3;  // Levenberg-Marquardt: a point far along its rays is weakly fixed in depth
  bool converged = false;
  for (int iteration = 0; iteration < 20 && !converged; ++iteration) {
    Matrix3d normal = Matrix3d::Zero();
    Vector3d gradient = Vector3d::Zero();
    for (size_t i = 0; i < views; ++i) {
      const Vector3d y_full = cam_from_world[i].rotation * x + cam_from_world[i].translation;
      const double norm = y_full.norm();
      const Vector3d y = y_full / norm;
      const Matrix3d dy_dx = (Matrix3d::Identity() - y * y.transpose()) / norm * cam_from_world[i].rotation;
      Eigen::Matrix<double, 2, 3> jacobian;
      jacobian.row(0) = focal_length_px * bases[i].first.transpose() * dy_dx;
      jacobian.row(1) = focal_length_px * bases[i].second.transpose() * dy_dx;
      const Vector2d residual(focal_length_px * bases[i].first.dot(y), focal_length_px * bases[i].second.dot(y));
      normal += jacobian.transpose() * jacobian;
      gradient += jacobian.transpose() * residual;
    }
    bool improved = false;
    for (int attempt = 0; attempt < 10 && !improved; ++attempt) {
      Matrix3d damped = normal;
      damped.diagonal() *= 1.0 + damping;
      const Vector3d step = damped.ldlt().solve(-gradient);
      if (!step.allFinite()) return false;
      const double next = cost(x + step);
      if (next < current) {
        x += step;
        improved = true;
        damping = std::max(1e-6, damping * 0.3);
        converged = current - next < 1e-12 * (1.0 + current);
        current = next;
      } else {
        damping *= 10.0;
      }
    }
    if (!improved) break;
  }
  if (!x.allFinite() || !std::isfinite(current)) return false;
  *point = x;
  if (max_residual_px != nullptr) {
    *max_residual_px = 0.0;
    for (size_t i = 0; i < views; ++i) {
      const Vector3d y = cam_from_world[i].rotation * x + cam_from_world[i].translation;
      *max_residual_px = std::max(*max_residual_px, tangent_residual(i, y).norm());
    }
  }
  return true;
}

}  // namespace retrace
