#include "retrace/util/statistics.h"

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace retrace {
namespace {

TEST(StatisticsTest, QuantileIsTheElementOfRankFloorQN) {
  const std::vector<double> values = {5, 1, 4, 2, 3, 10, 9, 8, 7, 6};  // 1..10 shuffled
  EXPECT_EQ(Quantile(values, 0.0), 1.0);
  EXPECT_EQ(Quantile(values, 0.5), 6.0);    // rank 5 of 0..9
  EXPECT_EQ(Quantile(values, 0.95), 10.0);  // rank 9
  EXPECT_EQ(Quantile(values, 1.0), 10.0);
  EXPECT_EQ(Quantile({}, 0.5), 0.0);
  EXPECT_EQ(Quantile({7.5}, 0.95), 7.5);
}

TEST(StatisticsTest, MedianAveragesTheTwoMiddleValuesOfAnEvenCount) {
  EXPECT_EQ(Median({}), 0.0);
  EXPECT_EQ(Median({3.0, 1.0, 2.0}), 2.0);
  EXPECT_EQ(Median({4.0, 1.0, 3.0, 2.0}), 2.5);
}

TEST(StatisticsTest, RobustSigmaAboutIsScaledMedianAbsoluteDeviation) {
  EXPECT_EQ(RobustSigmaAbout({}, 1.0), 0.0);
  // Deviations from 10: 3, 1, 0, 2, 100 → median 2; the outlier does not move it.
  EXPECT_NEAR(RobustSigmaAbout({7.0, 11.0, 10.0, 12.0, 110.0}, 10.0), 1.4826 * 2.0, 1e-12);
  // Gaussian values: the σ they were drawn with.
  std::mt19937 random(3);
  std::normal_distribution<double> gaussian(5.0, 0.7);
  std::vector<double> values(20000);
  for (double& v : values) v = gaussian(random);
  EXPECT_NEAR(RobustSigmaAbout(values, 5.0), 0.7, 0.02);
}

// `count` Gaussian values (σ 1), each drawn value repeated `run` times in a row (errors that come in runs of frames).
std::vector<double> GaussianRuns(size_t count, size_t run, uint32_t seed) {
  std::mt19937 random(seed);
  std::normal_distribution<double> gaussian(0.0, 1.0);
  std::vector<double> values;
  while (values.size() < count) values.insert(values.end(), run, gaussian(random));
  values.resize(count);
  return values;
}

TEST(StatisticsTest, PairedMedianDifferenceStandardErrorOfIndependentGaussians) {
  // Two independent samples of n Gaussians: the median's standard error is sqrt(pi / 2) σ / sqrt(n) (its asymptotic
  // variance 1 / (4 n f(0)^2)), the difference's sqrt(2) times that: sqrt(pi / n), 0.0396 for n = 2000. One
  // bootstrap estimate spreads by about 7 % around it (a median's bootstrap converges slowly), so the mean over five
  // samples is compared, within 15 %: a factor sqrt(2) either way is outside.
  const size_t n = 2000;
  const int samples = 5, resamples = 500;
  double sum = 0.0;
  for (int sample = 0; sample < samples; ++sample) {
    const std::vector<double> a = GaussianRuns(n, 1, 100 + 2 * sample), b = GaussianRuns(n, 1, 101 + 2 * sample);
    sum += PairedMedianDifferenceStandardError(a, b, 1, resamples);
  }
  const double expected = std::sqrt(M_PI / n);
  EXPECT_NEAR(sum / samples, expected, 0.15 * expected);
  // The same answer on every call (a seeded generator).
  const std::vector<double> a = GaussianRuns(n, 1, 11), b = GaussianRuns(n, 1, 12);
  EXPECT_EQ(PairedMedianDifferenceStandardError(a, b, 1, resamples),
            PairedMedianDifferenceStandardError(a, b, 1, resamples));
}

TEST(StatisticsTest, PairedMedianDifferenceStandardErrorOfPairsThatMoveTogether) {
  // b = a + 0.3 pair by pair: every resample's medians differ by exactly 0.3, no spread.
  const std::vector<double> a = GaussianRuns(500, 1, 5);
  std::vector<double> b;
  for (const double v : a) b.push_back(v + 0.3);
  EXPECT_NEAR(PairedMedianDifferenceStandardError(a, b, 1), 0.0, 1e-12);
  EXPECT_NEAR(PairedMedianDifferenceStandardError(a, b, 10), 0.0, 1e-12);
}

TEST(StatisticsTest, PairedMedianDifferenceStandardErrorNeedsBlocksAsLongAsTheRuns) {
  // 4000 values in runs of 20 equal ones are 200 independent draws: the difference's standard error is sqrt(pi /
  // 200) = 0.125. Blocks of 20 pairs see that (the mean over eight samples within 20 %; blocks that start anywhere run
  // about 14 % low here); single pairs take the 4000 for independent and find 0.03-0.04 (sqrt(pi / 4000) = 0.028
  // without the ties), what the block length is for.
  const size_t n = 4000, run = 20;
  const int samples = 8, resamples = 500;
  double blocks = 0.0, single = 0.0;
  for (int sample = 0; sample < samples; ++sample) {
    const std::vector<double> a = GaussianRuns(n, run, 200 + 2 * sample), b = GaussianRuns(n, run, 201 + 2 * sample);
    blocks += PairedMedianDifferenceStandardError(a, b, run, resamples) / samples;
    single += PairedMedianDifferenceStandardError(a, b, 1, resamples) / samples;
  }
  const double expected = std::sqrt(M_PI / (n / run));
  EXPECT_NEAR(blocks, expected, 0.2 * expected);
  EXPECT_LT(single, 0.4 * expected);
}

TEST(StatisticsTest, PairedMedianDifferenceStandardErrorOfTooFewPairs) {
  const std::vector<double> a = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10}, b = {2, 1, 4, 3, 6, 5, 8, 7, 10, 9};
  EXPECT_EQ(PairedMedianDifferenceStandardError(a, b, 6), 0.0);  // fewer than two blocks
  EXPECT_EQ(PairedMedianDifferenceStandardError(a, b, 0), 0.0);
  EXPECT_EQ(PairedMedianDifferenceStandardError(a, {1.0, 2.0, 3.0}, 2), 0.0);  // the shorter one's 3 pairs
  EXPECT_GT(PairedMedianDifferenceStandardError(a, b, 1), 0.0);
}

}  // namespace
}  // namespace retrace
