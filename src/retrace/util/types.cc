#include "retrace/util/types.h"

#include <algorithm>
#include <cmath>

namespace retrace {

double RotationErrorDeg(const Matrix3d& a, const Matrix3d& b) {
  const Matrix3d delta = a.transpose() * b;
  const double cos_angle = std::clamp((delta.trace() - 1.0) / 2.0, -1.0, 1.0);
  return std::acos(cos_angle) * 180.0 / M_PI;
}

double AngleBetweenDeg(const Vector3d& a, const Vector3d& b) {
  // atan2 of |a x b| and a.b is accurate also for tiny angles, unlike acos.
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI;
}

}  // namespace retrace
