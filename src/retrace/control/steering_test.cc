#include "retrace/control/steering.h"

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

}  // namespace
}  // namespace retrace
