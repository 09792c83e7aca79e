#include "retrace/teach/link_verification.h"

#include <gtest/gtest.h>

namespace retrace {
namespace {

Rigid3d Pose(double yaw, const Vector3d& position) {
  return Rigid3d(Eigen::AngleAxisd(yaw, Vector3d::UnitY()).toRotationMatrix(), position);
}

// Relative pose b_from_a of two world_from_cam poses with its translation scaled to `length`.
Rigid3d Relative(const Rigid3d& world_from_a, const Rigid3d& world_from_b, double length = 1.0) {
  Rigid3d b_from_a = world_from_b.Inverse() * world_from_a;
  b_from_a.translation = length * b_from_a.translation.normalized();
  return b_from_a;
}

TEST(LinkVerification, TrueMotionsAgreeWhateverTheirScales) {
  const Rigid3d x = Pose(0.1, Vector3d(0, 0, 0)), y = Pose(0.5, Vector3d(2, 0.1, 9)), z = Pose(0.7, Vector3d(3, 0, 12));
  for (const double scale : {0.01, 1.0, 100.0}) {
    const MotionAgreement agreement = CompareComposedMotion(Relative(x, y), Relative(y, z, scale), Relative(x, z, 3.0));
    EXPECT_NEAR(agreement.rotation_deg, 0.0, 1e-6);
    EXPECT_NEAR(agreement.direction_deg, 0.0, 1e-6);
  }
}

TEST(LinkVerification, RotationDisagreementIsMeasured) {
  const Rigid3d x = Pose(0.0, Vector3d(0, 0, 0)), y = Pose(0.2, Vector3d(1, 0, 5)), z = Pose(0.3, Vector3d(1, 0, 8));
  Rigid3d measured = Relative(x, z);
  measured.rotation = Eigen::AngleAxisd(3.0 * M_PI / 180, Vector3d::UnitY()).toRotationMatrix() * measured.rotation;
  const MotionAgreement agreement = CompareComposedMotion(Relative(x, y), Relative(y, z), measured);
  EXPECT_NEAR(agreement.rotation_deg, 3.0, 1e-6);
}

TEST(LinkVerification, DirectionOutsideTheComposedArcIsMeasured) {
  // Straight road: x, y, z one behind the other along the optical axis, no rotation.
  const Rigid3d x = Pose(0, Vector3d(0, 0, 0)), y = Pose(0, Vector3d(0, 0, 4)), z = Pose(0, Vector3d(0, 0, 7));
  // A measured motion that puts z 20 degrees to the side of the road: 20 degrees off the arc (a single direction
  // here, both parts pointing the same way).
  Rigid3d measured = Relative(x, z);
  measured.translation = Eigen::AngleAxisd(20.0 * M_PI / 180, Vector3d::UnitY()) * measured.translation;
  EXPECT_NEAR(CompareComposedMotion(Relative(x, y), Relative(y, z), measured).direction_deg, 20.0, 1e-6);
  // The reverse direction (z behind x) is as far from the composition as can be.
  measured.translation = -Relative(x, z).translation;
  EXPECT_NEAR(CompareComposedMotion(Relative(x, y), Relative(y, z), measured).direction_deg, 180.0, 1e-6);
}

TEST(LinkVerification, DirectionBetweenThePartsAgrees) {
  // x -> y sideways, y -> z forwards: any direction between the two (in the camera of z) is some choice of scales;
  // one out of their plane is not.
  const Rigid3d x = Pose(0, Vector3d(0, 0, 0)), y = Pose(0, Vector3d(5, 0, 0)), z = Pose(0, Vector3d(5, 0, 5));
  const Rigid3d y_from_x = Relative(x, y), z_from_y = Relative(y, z);
  Rigid3d measured = Relative(x, z);
  EXPECT_NEAR(CompareComposedMotion(y_from_x, z_from_y, measured).direction_deg, 0.0, 1e-6);
  measured.translation = Vector3d(-1, 0, -0.2).normalized();  // x's centre seen from z: left and slightly behind
  EXPECT_NEAR(CompareComposedMotion(y_from_x, z_from_y, measured).direction_deg, 0.0, 1e-6);
  measured.translation = Vector3d(-1, std::tan(5.0 * M_PI / 180), -1).normalized();
  EXPECT_NEAR(CompareComposedMotion(y_from_x, z_from_y, measured).direction_deg, 5.0 / std::sqrt(2.0), 0.1);
  // Beyond the end of the arc: the angle to the nearer end.
  measured.translation = Vector3d(1, 0, -1).normalized();
  EXPECT_NEAR(CompareComposedMotion(y_from_x, z_from_y, measured).direction_deg, 45.0, 1e-6);
}

TEST(LinkVerification, KnownScaleLeavesOneDirection) {
  // x -> y sideways (5 m), y -> z forwards (5 m): with the true ratio of their lengths the true measured motion
  // agrees; a direction elsewhere on the arc, which any ratio would allow, does not.
  const Rigid3d x = Pose(0, Vector3d(0, 0, 0)), y = Pose(0, Vector3d(5, 0, 0)), z = Pose(0, Vector3d(5, 0, 5));
  const Rigid3d y_from_x = Relative(x, y), z_from_y = Relative(y, z, 7.0);
  Rigid3d measured = Relative(x, z);
  EXPECT_NEAR(CompareComposedMotion(y_from_x, z_from_y, measured, 1.0).direction_deg, 0.0, 1e-6);
  EXPECT_NEAR(CompareComposedMotion(y_from_x, z_from_y, measured, 1.0).rotation_deg, 0.0, 1e-6);
  measured.translation = Vector3d(-1, 0, -0.2).normalized();
  EXPECT_NEAR(CompareComposedMotion(y_from_x, z_from_y, measured).direction_deg, 0.0, 1e-6);
  EXPECT_NEAR(CompareComposedMotion(y_from_x, z_from_y, measured, 1.0).direction_deg,
              45.0 - std::atan(0.2) * 180 / M_PI, 1e-6);
}

}  // namespace
}  // namespace retrace
