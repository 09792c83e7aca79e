#include "retrace/geometry/scale.h"

#include <random>

#include <gtest/gtest.h>

namespace retrace {
namespace {

TEST(Scale, ExactOnNoiseFreeData) {
  // Geometry 1: camera A at the origin; geometry 2 shares camera A's successor... here both reconstruct the same
  // points seen from a shared camera, with different units and frames.
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  const Rigid3d shared_from_1(Eigen::AngleAxisd(0.3, Vector3d::UnitY()).toRotationMatrix(), Vector3d(0.5, 0, -1));
  const Rigid3d shared_from_2(Eigen::AngleAxisd(-0.2, Vector3d::UnitX()).toRotationMatrix(), Vector3d(0, 0.1, 0.4));
  const double true_scale = 3.7;  // lengths in geometry 1 = 3.7 x lengths in geometry 2
  std::vector<Vector3d> p1, p2;
  for (int i = 0; i < 40; ++i) {
    const Vector3d in_shared(u(rng), u(rng), 8.0 + u(rng));
    p1.push_back(shared_from_1.Inverse() * in_shared);
    p2.push_back(shared_from_2.Inverse() * (in_shared / true_scale));
  }
  const ScaleEstimate s = EstimateScale(p1, shared_from_1, p2, shared_from_2);
  ASSERT_TRUE(s.success);
  EXPECT_NEAR(s.scale, true_scale, 1e-12);
  EXPECT_EQ(s.num_votes, 40);
  EXPECT_NEAR(s.log_mad, 0.0, 1e-12);
}

TEST(Scale, RobustToThirtyPercentOutliers) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> depth(2.0, 40.0);
  std::normal_distribution<double> noise(0.0, 0.01);
  std::uniform_real_distribution<double> wild(0.05, 20.0);
  const double true_scale = 0.42;
  std::vector<double> d1, d2;
  for (int i = 0; i < 200; ++i) {
    const double d = depth(rng);
    d1.push_back(d * (1.0 + noise(rng)));
    // 30 % of the votes are gross outliers (wrong associations): any ratio.
    d2.push_back(i % 10 < 3 ? d * wild(rng) : d / true_scale * (1.0 + noise(rng)));
  }
  const ScaleEstimate s = EstimateScaleFromDistances(d1, d2);
  ASSERT_TRUE(s.success);
  EXPECT_NEAR(s.scale / true_scale, 1.0, 0.01);
}

TEST(Scale, FailsWithoutValidVotes) {
  EXPECT_FALSE(EstimateScaleFromDistances({}, {}).success);
  EXPECT_FALSE(EstimateScaleFromDistances({1.0}, {1.0, 2.0}).success);
  EXPECT_FALSE(EstimateScaleFromDistances({-1.0, 0.0}, {1.0, 1.0}).success);
  EXPECT_FALSE(EstimateScaleFromDistances({1.0, 2.0}, {1.0, 2.0}, 3).success);
  const ScaleEstimate s = EstimateScaleFromDistances({1.0, NAN, 4.0}, {2.0, 1.0, 8.0});
  ASSERT_TRUE(s.success);
  EXPECT_EQ(s.num_votes, 2);
  EXPECT_NEAR(s.scale, 0.5, 1e-12);
}

}  // namespace
}  // namespace retrace
