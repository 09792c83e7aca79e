#include "retrace/util/types.h"

#include <algorithm>
#include <cmath>

namespace retrace {

double RotationErrorDeg(const Matrix3d& a, const Matrix3d& b) {
  // Through the quaternion, which stays accurate for tiny angles where acos((trace - 1) / 2) does not.
  const Eigen::Quaterniond delta(a.transpose() * b);
  return 2.0 * std::atan2(delta.vec().norm(), std::abs(delta.w())) * 180.0 / M_PI;
}

double AngleBetweenDeg(const Vector3d& a, const Vector3d& b) {
  // atan2 of |a x b| and a.b is accurate also for tiny angles, unlike acos.
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI;
}

}  // namespace retrace
