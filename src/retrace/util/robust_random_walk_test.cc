#include "retrace/util/robust_random_walk.h"

#include <cmath>
#include <vector>

#include <gtest/gtest.h>

namespace retrace {
namespace {

TEST(CombineCarriedObservations, NoneIsInvalidAndOneIsItself) {
  EXPECT_FALSE(CombineCarriedObservations({}, 0.1, 10.0).valid);
  const CombinedObservation one = CombineCarriedObservations({{2.5, 0.1, 0.0, 0}}, 0.1, 10.0);
  ASSERT_TRUE(one.valid);
  EXPECT_NEAR(one.value, 2.5, 1e-12);
  EXPECT_NEAR(one.sigma, 0.1, 1e-3);  // over the responsibility of a lone observation (just below 1)
  EXPECT_EQ(one.inliers, 1);
}

TEST(CombineCarriedObservations, RightObservationsAverageByTheirVariances) {
  // Two observations at x's place: the inverse-variance mean and its σ.
  const CombinedObservation two = CombineCarriedObservations({{1.0, 0.1, 0.0, 0}, {2.0, 0.2, 0.0, 0}}, 0.0, 10.0);
  ASSERT_TRUE(two.valid);
  EXPECT_NEAR(two.value, (1.0 / 0.01 + 2.0 / 0.04) / (1 / 0.01 + 1 / 0.04), 1e-9);
  EXPECT_NEAR(two.sigma, 1.0 / std::sqrt(1 / 0.01 + 1 / 0.04), 1e-9);
}

TEST(CombineCarriedObservations, ARunOfWrongOnesIsOutvotedAndNotAveraged) {
  // Eight observations behind x agree on 1.0; three nearer ones, sure of themselves, say 0.0 (a run of wrong
  // frames). The estimate is the majority's, not a compromise.
  std::vector<CarriedObservation> observations;
  for (int k = 1; k <= 8; ++k) observations.push_back({1.0 + (k % 2 ? 0.02 : -0.02), 0.05, 0.0004 * (k + 3), -1});
  for (int k = 0; k < 3; ++k) observations.push_back({0.0, 0.02, 0.0004 * k, k == 0 ? 0 : -1});
  const CombinedObservation combined = CombineCarriedObservations(observations, 0.1, 10.0);
  ASSERT_TRUE(combined.valid);
  EXPECT_NEAR(combined.value, 1.0, 0.05);
  EXPECT_EQ(combined.inliers, 8);
}

}  // namespace
}  // namespace retrace
