#include "retrace/util/robust_random_walk.h"

#include <cmath>
#include <string>
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

TEST(ObservationWindow, CombinesTheRecentObservationsAsCarriedToTheLatest) {
  ObservationWindowOptions options;
  options.window = 10.0;
  options.process_sigma = 0.05;
  ObservationWindow window(options);
  EXPECT_FALSE(window.Combine().valid);
  // One observation every 2 units of distance; the window keeps those within 10 units of the latest.
  for (int k = 0; k <= 10; ++k) window.Add(2.0 * k, 1.0 + 0.01 * k, 0.1);
  EXPECT_EQ(window.size(), 6u);  // distances 10 ... 20
  std::vector<CarriedObservation> carried;
  for (int k = 5; k <= 10; ++k) {
    const double behind = 20.0 - 2.0 * k;
    carried.push_back({1.0 + 0.01 * k, 0.1, 0.0025 * behind, behind > 0 ? -1 : 0});
  }
  const CombinedObservation expected = CombineCarriedObservations(carried, 0.1, 10.0);
  const CombinedObservation combined = window.Combine();
  ASSERT_TRUE(combined.valid);
  EXPECT_DOUBLE_EQ(combined.value, expected.value);
  EXPECT_DOUBLE_EQ(combined.sigma, expected.sigma);
  // Combining several right observations narrows the estimate below one observation's σ.
  EXPECT_LT(combined.sigma, 0.1);
  window.Clear();
  EXPECT_EQ(window.size(), 0u);
}

TEST(ObservationWindow, KeepsAtMostMaxObservationsAndRaisesSmallSigmas) {
  ObservationWindowOptions options;
  options.max_observations = 4;
  options.min_sigma = 0.02;
  ObservationWindow window(options);
  for (int k = 0; k < 10; ++k) window.Add(0.0, 0.5, 0.001);  // standing still: no distance, many observations
  EXPECT_EQ(window.size(), 4u);
  const CombinedObservation combined = window.Combine();
  ASSERT_TRUE(combined.valid);
  EXPECT_NEAR(combined.value, 0.5, 1e-12);
  // Four observations of σ 0.02 (the floor, not 0.001) at one place: 0.01.
  EXPECT_NEAR(combined.sigma, 0.01, 1e-3);
}

TEST(ObservationWindowOptions, RefusesWhatCannotBeCombined) {
  ObservationWindowOptions options;
  EXPECT_TRUE(options.Check());
  options.min_sigma = 0.0;
  std::string error;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("min_sigma"), std::string::npos);
  options = ObservationWindowOptions();
  options.outlier_probability = 1.0;
  EXPECT_FALSE(options.Check());
  options = ObservationWindowOptions();
  options.window = -1.0;
  EXPECT_FALSE(options.Check());
}

}  // namespace
}  // namespace retrace
