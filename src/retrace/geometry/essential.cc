#include "retrace/geometry/essential.h"

#include <cmath>
#include <limits>

#include <Eigen/SVD>

namespace retrace {

Matrix3d CrossProductMatrix(const Vector3d& v) {
  Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

Matrix3d ExpSO3(const Vector3d& w) {
  const double angle = w.norm();
  if (angle < 1e-12) return Matrix3d::Identity() + CrossProductMatrix(w);
  return Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
}

Matrix3d EssentialFromPose(const Rigid3d& b_from_a) {
  return CrossProductMatrix(b_from_a.translation) * b_from_a.rotation;
}

bool DecomposeEssential(const Matrix3d& e, Rigid3d poses[4]) {
  if (!e.allFinite()) return false;
  const Eigen::JacobiSVD<Matrix3d> svd(e, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Vector3d s = svd.singularValues();
  if (!(s(1) > 1e-9 * s(0)) || !(s(0) > 0.0)) return false;
  Matrix3d u = svd.matrixU();
  Matrix3d v = svd.matrixV();
  // Proper rotations: flipping the last column changes neither E's null space nor [t]ₓR up to sign.
  if (u.determinant() < 0.0) u.col(2) *= -1.0;
  if (v.determinant() < 0.0) v.col(2) *= -1.0;
  Matrix3d w;
  w << 0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0;
  const Matrix3d r1 = u * w * v.transpose();
  const Matrix3d r2 = u * w.transpose() * v.transpose();
  const Vector3d t = u.col(2).normalized();
  poses[0] = Rigid3d(r1, t);
  poses[1] = Rigid3d(r1, -t);
  poses[2] = Rigid3d(r2, t);
  poses[3] = Rigid3d(r2, -t);
  return true;
}

namespace {

// Numerator f_Bᵀ E f_A and the squared norm of its gradient restricted to the two tangent planes.
inline void SampsonParts(const Matrix3d& e, const Vector3d& fa, const Vector3d& fb, double* c, double* grad2) {
  const Vector3d e_fa = e * fa;            // gradient w.r.t. f_B
  const Vector3d et_fb = e.transpose() * fb;  // gradient w.r.t. f_A
  *c = fb.dot(e_fa);
  const double ga_along = et_fb.dot(fa);
  const double gb_along = e_fa.dot(fb);
  *grad2 = (et_fb.squaredNorm() - ga_along * ga_along) + (e_fa.squaredNorm() - gb_along * gb_along);
}

}  // namespace

double SampsonErrorSquared(const Matrix3d& e, const Vector3d& bearing_a, const Vector3d& bearing_b) {
  double c, grad2;
  SampsonParts(e, bearing_a, bearing_b, &c, &grad2);
  if (!(grad2 > 1e-300)) return c == 0.0 ? 0.0 : std::numeric_limits<double>::infinity();
  return c * c / grad2;
}

double SampsonResidual(const Matrix3d& e, const Vector3d& bearing_a, const Vector3d& bearing_b) {
  double c, grad2;
  SampsonParts(e, bearing_a, bearing_b, &c, &grad2);
  if (!(grad2 > 1e-300)) return c == 0.0 ? 0.0 : 1.0;
  return c / std::sqrt(grad2);
}

}  // namespace retrace
