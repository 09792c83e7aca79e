#include "retrace/control/steering.h"

#include <cmath>

#include <gtest/gtest.h>

namespace retrace {
namespace {

Vector3d Bearing(double x, double y) { return Vector3d(x, y, 1.0).normalized(); }

TEST(SteerByImage, MeanHorizontalOffsetTimesTheGain) {
  // The features appear 0.1 (normalised) right of where the next key-image sees them: the robot points left of
  // the route, and w > 0 turns it right.
  std::vector<SteeringFeature> features;
  for (double x : {-0.5, 0.0, 0.3}) features.push_back({Bearing(x + 0.1, 0.2), Bearing(x, -0.1)});
  const SteeringCommand command = SteerByImage(features, 2.0);
  ASSERT_TRUE(command.valid);
  EXPECT_EQ(command.features, 3);
  EXPECT_NEAR(command.angle, 0.2, 1e-12);
  // Seen exactly where the key-image sees them: straight on.
  features = {{Bearing(0.4, 0.0), Bearing(0.4, 0.3)}};
  EXPECT_NEAR(SteerByImage(features, 1.0).angle, 0.0, 1e-12);
}

TEST(SteerByImage, SkipsFeaturesBehindACameraAndIsInvalidWithoutFeatures) {
  std::vector<SteeringFeature> features = {{Vector3d(0.1, 0, -1).normalized(), Bearing(0.0, 0.0)},
                                           {Bearing(0.0, 0.0), Vector3d(0.1, 0, -1).normalized()}};
  const SteeringCommand command = SteerByImage(features, 1.0);
  EXPECT_FALSE(command.valid);
  EXPECT_EQ(command.angle, 0.0);
  EXPECT_FALSE(SteerByImage({}, 1.0).valid);
  features.push_back({Bearing(-0.2, 0.0), Bearing(0.0, 0.0)});
  EXPECT_NEAR(SteerByImage(features, 1.0).angle, -0.2, 1e-12);
}

// An omnidirectional camera 1 m right of the taught line, heading along it, 4 m before the key-image, between two
// walls 5 m to each side: within a forward field of 45° the law averages the features ahead only (|x| <= 1 in both
// images) and turns the robot back to the left (w < 0); a feature at 60° alone gives no command.
TEST(SteerByImage, OnlyTheForwardFieldCounts) {
  std::vector<SteeringFeature> features;
  const Vector3d robot(1.0, 0.0, 0.0), key_image(0.0, 0.0, 4.0);
  int in_field = 0;
  for (double z = 0.5; z <= 30.0; z += 0.5) {
    for (double side : {-5.0, 5.0}) {
      const Vector3d point(side, 0.0, z);
      features.push_back({(point - robot).normalized(), (point - key_image).normalized()});
      const Vector3d a = point - robot, b = point - key_image;
      in_field += a.z() > 0 && b.z() > 0 && std::abs(a.x() / a.z()) <= 1.0 && std::abs(b.x() / b.z()) <= 1.0;
    }
  }
  const SteeringCommand all = SteerByImage(features, 1.0);
  const SteeringCommand ahead = SteerByImage(features, 1.0, 1.0);
  ASSERT_TRUE(ahead.valid);
  EXPECT_EQ(ahead.features, in_field);
  EXPECT_LT(ahead.features, all.features);
  EXPECT_LT(ahead.angle, 0.0);
  const std::vector<SteeringFeature> beside = {{Bearing(std::tan(M_PI / 3), 0.0), Bearing(std::tan(M_PI / 3), 0.0)}};
  EXPECT_FALSE(SteerByImage(beside, 1.0, 1.0).valid);
  EXPECT_TRUE(SteerByImage(beside, 1.0).valid);
}

}  // namespace
}  // namespace retrace
