#include "retrace/util/statistics.h"

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

}  // namespace
}  // namespace retrace
