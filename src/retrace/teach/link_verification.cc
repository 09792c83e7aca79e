#include "retrace/teach/link_verification.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace retrace {
namespace {

// Angle (degrees) from the unit direction m to the set {normalize(a u + b v) : a, b >= 0}, the shorter great-circle
// arc from u to v (unit directions).
double AngleToArcDeg(const Vector3d& m, const Vector3d& u, const Vector3d& v) {
  const double to_ends = std::min(AngleBetweenDeg(m, u), AngleBetweenDeg(m, v));
  const Vector3d normal = u.cross(v);
  if (normal.norm() < 1e-9) return to_ends;  // parallel or opposite: the arc is its end points
  // The closest point of the arc's great circle to m is m projected onto the plane of u and v; it belongs to the
  // arc when it is a non-negative combination of u and v.
  const Vector3d n = normal.normalized();
  const Vector3d p = m - m.dot(n) * n;
  if (p.norm() < 1e-12) return to_ends;
  const double uv = u.dot(v), pu = p.dot(u), pv = p.dot(v);
  const double det = 1.0 - uv * uv;
  const double a = (pu - uv * pv) / det, b = (pv - uv * pu) / det;
  if (a < 0 || b < 0) return to_ends;
  return std::min(to_ends, AngleBetweenDeg(m, p));
}

}  // namespace

MotionAgreement CompareComposedMotion(const Rigid3d& y_from_x, const Rigid3d& z_from_y, const Rigid3d& z_from_x) {
  MotionAgreement agreement;
  agreement.rotation_deg = RotationErrorDeg(z_from_y.rotation * y_from_x.rotation, z_from_x.rotation);
  // x_Z = R_ZY (R_YX x_X + λ t_YX) + μ t_ZY: the translation is λ R_ZY t_YX + μ t_ZY with unknown λ, μ >= 0.
  const Vector3d first = z_from_y.rotation * y_from_x.translation;
  const Vector3d& second = z_from_y.translation;
  const Vector3d& measured = z_from_x.translation;
  if (measured.norm() == 0.0) return agreement;
  if (first.norm() == 0.0 && second.norm() == 0.0) return agreement;
  if (first.norm() == 0.0) {
    agreement.direction_deg = AngleBetweenDeg(measured, second);
  } else if (second.norm() == 0.0) {
    agreement.direction_deg = AngleBetweenDeg(measured, first);
  } else {
    agreement.direction_deg = AngleToArcDeg(measured.normalized(), first.normalized(), second.normalized());
  }
  return agreement;
}

MotionAgreement CompareComposedMotion(const Rigid3d& y_from_x, const Rigid3d& z_from_y, const Rigid3d& z_from_x,
                                      double scale) {
  MotionAgreement agreement = CompareComposedMotion(y_from_x, z_from_y, z_from_x);
  const Vector3d& first = y_from_x.translation;
  const Vector3d& second = z_from_y.translation;
  const Vector3d& measured = z_from_x.translation;
  if (!(scale > 0) || first.norm() == 0.0 || second.norm() == 0.0 || measured.norm() == 0.0) return agreement;
  const Vector3d composed = z_from_y.rotation * first.normalized() + scale * second.normalized();
  if (composed.norm() < 1e-9) return agreement;  // the two parts cancel: no direction to compare
  agreement.direction_deg = AngleBetweenDeg(measured, composed);
  return agreement;
}

LinkDirection LinkDirectionOfTravel(const Rigid3d* x_from_p, const Rigid3d& y_from_x, const Rigid3d* s_from_y) {
  // x_B = R x_A + t: A's centre in B's frame is t, B's centre in A's frame -R^T t.
  const auto cosine = [](const Vector3d& u, const Vector3d& v) {
    const double norms = u.norm() * v.norm();
    return norms > 0.0 ? u.dot(v) / norms : std::numeric_limits<double>::quiet_NaN();
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  LinkDirection direction;
  // At X, in X's frame: travel from P's centre (x_from_p.t) to X's (0); the step from X (0) to Y's centre.
  const Vector3d step_at_x = -(y_from_x.rotation.transpose() * y_from_x.translation);
  direction.at_from = x_from_p != nullptr ? cosine(-x_from_p->translation, step_at_x) : nan;
  // At Y, in Y's frame: travel from Y (0) to S's centre; the step from X's centre (y_from_x.t) to Y (0).
  direction.at_to = s_from_y != nullptr
                        ? cosine(-(s_from_y->rotation.transpose() * s_from_y->translation), -y_from_x.translation)
                        : nan;
  return direction;
}

}  // namespace retrace
