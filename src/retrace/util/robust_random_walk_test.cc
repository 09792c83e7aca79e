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

TEST(CombineCarriedObservations, AGroupSharingItsErrorsCountsForLessThanItsNumber) {
  // n observations of one group, each with σ, pairwise correlated by ρ: their mean has the variance
  // σ² (1 + (n - 1) ρ) / n, and against independent ones they weigh as that one mean does.
  const int n = 16;
  const double sigma = 0.1, rho = 0.6;
  std::vector<CarriedObservation> group;
  for (int k = 0; k < n; ++k) group.push_back({0.5, sigma, 0.0, 0, /*group=*/7});
  const CombinedObservation alone = CombineCarriedObservations(group, 0.0, 10.0, rho);
  ASSERT_TRUE(alone.valid);
  EXPECT_NEAR(alone.value, 0.5, 1e-9);
  EXPECT_NEAR(alone.sigma, sigma * std::sqrt((1 + (n - 1) * rho) / n), 1e-9);
  // Four independent observations at 0 (each its own group) and the sixteen at 0.5: information 4 / σ² against
  // n / (σ² (1 + (n - 1) ρ)) = 160 / 400 of it, so the estimate is 0.5 · 160 / 560 — not the 0.4 of twenty
  // independent observations, which ρ = 0 gives.
  std::vector<CarriedObservation> mixed = group;
  for (int k = 0; k < 4; ++k) mixed.push_back({0.0, sigma, 0.0, 0, /*group=*/k});
  EXPECT_NEAR(CombineCarriedObservations(mixed, 0.0, 10.0, rho).value, 0.5 * 160.0 / 560.0, 1e-9);
  EXPECT_NEAR(CombineCarriedObservations(mixed, 0.0, 10.0, 0.0).value, 0.4, 1e-9);
  EXPECT_FALSE(CombineCarriedObservations(mixed, 0.0, 10.0, 1.0).valid);  // ρ = 1 is singular: refused
}

TEST(ObservationWindow, ARunOfFramesOnOneArcDoesNotOutweighTheFramesBefore) {
  // The closed loop's seed111 (README, "Frames of one arc share their offset's error"): twelve frames on one arc
  // a metre off with σ 0.3 m after frames on other arcs right to a few centimetres.
  ObservationWindowOptions options;
  options.shared_correlation = 0.6;
  ObservationWindow correlated(options);
  options.shared_correlation = 0.0;
  ObservationWindow independent(options);
  for (int k = 0; k < 12; ++k) {
    correlated.Add(0.8 * k, 0.0, 0.05, k / 4);
    independent.Add(0.8 * k, 0.0, 0.05, k / 4);
  }
  for (int k = 12; k < 24; ++k) {
    correlated.Add(0.8 * k, -0.7, 0.3, 10);
    independent.Add(0.8 * k, -0.7, 0.3, 10);
  }
  EXPECT_GT(correlated.Combine().value, -0.25);
  EXPECT_LT(independent.Combine().value, -0.35);
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
  options = ObservationWindowOptions();
  options.shared_correlation = 1.0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("shared_correlation"), std::string::npos);
}

}  // namespace
}  // namespace retrace
