#include "retrace/nav/navigator.h"

#include <cmath>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

namespace retrace {
namespace {

using Eigen::AngleAxisd;

// Level frames of a robot on flat ground (y down, z ahead), rotated by `yaw` about the vertical (positive turns
// z towards x, to the right) at `position`.
Rigid3d WorldFromLevel(const Vector3d& position, double yaw) {
  return Rigid3d(AngleAxisd(yaw, Vector3d::UnitY()).toRotationMatrix(), position);
}

// A corner: key-image c at the crossing looking east (the world's +z), its successor n 5 m to the north (the world's
// -x, left of c) looking north; the camera is pitched down 5° on its mount. The robot stands at c's place, or a
// little past it, looking in various directions.
class HeadingAlongArcTest : public ::testing::TestWithParam<bool> {
 protected:
  HeadingAlongArcTest() {
    const Matrix3d camera_from_level = AngleAxisd(5.0 * M_PI / 180, Vector3d::UnitX()).toRotationMatrix();
    mount_ = Rigid3d(camera_from_level, Vector3d::Zero());
    world_from_c_ = WorldFromLevel(Vector3d::Zero(), 0.0);
    world_from_n_ = WorldFromLevel(Vector3d(-5, 0, 0), -M_PI / 2);
    // The taught arc between the cameras (x_to = R x_from + t, |t| = 1), c → n or n → c.
    const Rigid3d camera_c = world_from_c_ * mount_.Inverse();  // world_from_camera
    const Rigid3d camera_n = world_from_n_ * mount_.Inverse();
    MapArc arc;
    const bool forward = GetParam();
    arc.from = forward ? 0 : 1;
    arc.to = forward ? 1 : 0;
    const Rigid3d to_from_from = forward ? camera_n.Inverse() * camera_c : camera_c.Inverse() * camera_n;
    arc.to_from_from = Rigid3d(to_from_from.rotation, to_from_from.translation.normalized());
    for (node_t id : {0, 1}) {
      MapNode node;
      node.id = id;
      map_.AddNode(node);
    }
    map_.AddArc(arc);
  }

  // The heading from a robot at `world_from_robot` to n along the arc, and the true one.
  std::pair<double, double> Headings(const Rigid3d& world_from_robot) const {
    // The robot's geometry to c in the level frames: x_c = R x_robot + t.
    const Matrix3d c_from_robot = (world_from_c_.Inverse() * world_from_robot).rotation;
    const std::optional<double> heading =
        HeadingAlongArc(map_, 0, 1, c_from_robot, mount_.rotation.transpose());
    EXPECT_TRUE(heading.has_value());
    const Vector3d n_in_robot = world_from_robot.Inverse() * world_from_n_.translation;
    return {heading.value_or(NAN), std::atan2(n_in_robot.x(), n_in_robot.z())};
  }

  Rigid3d mount_;  // camera_from_level
  Rigid3d world_from_c_, world_from_n_;
  Map map_;
};

TEST_P(HeadingAlongArcTest, ExactAtThePassedKeyImage) {
  for (double yaw : {0.0, 0.4, -0.3, 1.2, M_PI}) {
    const auto [heading, truth] = Headings(WorldFromLevel(Vector3d::Zero(), yaw));
    EXPECT_NEAR(std::remainder(heading - truth, 2 * M_PI), 0.0, 1e-9) << "robot turned by " << yaw;
  }
}

TEST_P(HeadingAlongArcTest, RoughPastThePassedKeyImage) {
  // 2 m past c on the street it came along (the robot overshot the corner): n is ~110° to the left, the arc says 90°.
  const auto [heading, truth] = Headings(WorldFromLevel(Vector3d(0, 0, 2), 0.0));
  EXPECT_NEAR(heading, -M_PI / 2, 1e-9);
  EXPECT_NEAR(truth, -M_PI / 2 - std::atan2(2.0, 5.0), 1e-9);
}

INSTANTIATE_TEST_SUITE_P(EitherArcDirection, HeadingAlongArcTest, ::testing::Bool());

TEST(HeadingAlongArc, NoArcNoHeading) {
  Map map;
  for (node_t id : {0, 1, 2}) {
    MapNode node;
    node.id = id;
    map.AddNode(node);
  }
  MapArc arc;
  arc.from = 0;
  arc.to = 1;
  arc.to_from_from.translation = Vector3d(0, 0, -1);
  map.AddArc(arc);
  EXPECT_TRUE(HeadingAlongArc(map, 0, 1, Matrix3d::Identity(), Matrix3d::Identity()).has_value());
  EXPECT_FALSE(HeadingAlongArc(map, 0, 2, Matrix3d::Identity(), Matrix3d::Identity()).has_value());
}

}  // namespace
}  // namespace retrace
