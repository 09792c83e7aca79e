#include "retrace/teach/link_verification.h"

#include <cmath>

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

// A loop that comes back: the drive P -> X travels along +z and turns; its start Y lies 6 m ahead of X, and the
// drive went on from Y to S along Y's direction. The link continues the drive at both ends.
TEST(LinkVerification, ALinkAheadOfTheDriveMovesForward) {
  const Rigid3d p = Pose(0.0, Vector3d(0, 0, -4)), x = Pose(0.1, Vector3d(0, 0, 0));
  const Rigid3d y = Pose(0.2, Vector3d(1, 0, 6)), s = Pose(0.2, Vector3d(1.8, 0, 10));
  const Rigid3d x_from_p = Relative(p, x), y_from_x = Relative(x, y, 0.3), s_from_y = Relative(y, s, 7.0);
  const LinkDirection direction = LinkDirectionOfTravel(&x_from_p, y_from_x, &s_from_y);
  EXPECT_GT(direction.at_from, 0.9);
  EXPECT_GT(direction.at_to, 0.9);
}

// A straight drive's last key-image X linked to Y, passed 5 m before (kitti07 frames 0-39): the views agree, the
// direction does not — the link goes backwards at both ends whatever the links' scales. Without the arcs around
// it the direction is unknown (NaN).
TEST(LinkVerification, ALinkBackToAPlaceJustPassedMovesBackward) {
  const Rigid3d y = Pose(0.0, Vector3d(0, 0, 0)), s = Pose(0.0, Vector3d(0, 0, 2));
  const Rigid3d p = Pose(0.05, Vector3d(0.1, 0, 3)), x = Pose(0.05, Vector3d(0.3, 0, 5));
  const Rigid3d x_from_p = Relative(p, x, 2.0), y_from_x = Relative(x, y), s_from_y = Relative(y, s, 0.5);
  const LinkDirection direction = LinkDirectionOfTravel(&x_from_p, y_from_x, &s_from_y);
  EXPECT_LT(direction.at_from, -0.9);
  EXPECT_LT(direction.at_to, -0.9);
  const LinkDirection alone = LinkDirectionOfTravel(nullptr, y_from_x, nullptr);
  EXPECT_TRUE(std::isnan(alone.at_from));
  EXPECT_TRUE(std::isnan(alone.at_to));
}

}  // namespace
}  // namespace retrace
