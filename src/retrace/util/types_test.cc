#include "retrace/util/types.h"

#include <gtest/gtest.h>

namespace retrace {
namespace {

TEST(Rigid3d, InverseComposesToIdentity) {
  const Matrix3d r = Eigen::AngleAxisd(0.3, Vector3d(0.2, 1.0, -0.1).normalized()).toRotationMatrix();
  const Rigid3d b_from_a(r, Vector3d(1.0, -2.0, 0.5));
  const Rigid3d identity = b_from_a.Inverse() * b_from_a;
  EXPECT_LT(RotationErrorDeg(identity.rotation, Matrix3d::Identity()), 1e-9);
  EXPECT_LT(identity.translation.norm(), 1e-12);
  const Vector3d x(0.3, 0.4, 5.0);
  EXPECT_LT((b_from_a.Inverse() * (b_from_a * x) - x).norm(), 1e-12);
}

TEST(Angles, KnownValues) {
  const Matrix3d r = Eigen::AngleAxisd(10.0 * M_PI / 180.0, Vector3d::UnitY()).toRotationMatrix();
  EXPECT_NEAR(RotationErrorDeg(Matrix3d::Identity(), r), 10.0, 1e-9);
  EXPECT_NEAR(AngleBetweenDeg(Vector3d(1, 0, 0), Vector3d(1, 1, 0)), 45.0, 1e-9);
  EXPECT_NEAR(AngleBetweenDeg(Vector3d(0, 0, 1), Vector3d(0, 0, 2)), 0.0, 1e-12);
}

}  // namespace
}  // namespace retrace
