#include "retrace/util/statistics.h"

#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace retrace {
namespace {

TEST(StatisticsTest, QuantileIsTheElementOfRankFloorQN) {
  const std::vector<double> values = {5, 1, 4, 2, 3, 10, 9, 8, 7, 6};  // 1..10 shuffled
  EXPECT_EQ(Quantile(values, 0.0), 1.0);
  EXPECT_EQ(Quantile(values, 0.5), 6.0);   // rank 5 of 0..9
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

}  // namespace
}  // namespace retrace
