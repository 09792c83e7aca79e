#include "retrace/feature/hamming_nearest.h"

#include <limits>
#include <random>
#include <stdexcept>

#include <gtest/gtest.h>

namespace retrace {
namespace {

constexpr int kNone = std::numeric_limits<int>::max();

const HammingKernel kKernels[] = {HammingKernel::kPortable, HammingKernel::kPopcnt, HammingKernel::kAvx2,
                                  HammingKernel::kAvx512, HammingKernel::kAuto};

// Descriptors of few distinct bytes, so that many distances are equal: ties must go the same way in every kernel.
cv::Mat Descriptors(int rows, int bytes, std::mt19937* rng, int distinct_bytes) {
  cv::Mat descriptors(rows, bytes, CV_8U);
  std::uniform_int_distribution<int> pick(0, distinct_bytes - 1);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < bytes; ++c) descriptors.at<uint8_t>(r, c) = static_cast<uint8_t>((1u << pick(*rng)) - 1u);
  }
  return descriptors;
}

TEST(FindHammingNearest, KnownAnswerWithTies) {
  // Query 0 (all zero) is 8 bits from train 0, 0 from train 1, 1 from train 2; query 1 (byte 3 set) is 2 bits from
  // train 0, 8 from train 1, 9 from train 2.
  cv::Mat train = cv::Mat::zeros(3, 8, CV_8U), query = cv::Mat::zeros(2, 8, CV_8U);
  train.at<uint8_t>(0, 0) = 0x01;
  train.at<uint8_t>(0, 3) = 0xfe;
  train.at<uint8_t>(2, 7) = 0x80;
  query.at<uint8_t>(1, 3) = 0xff;
  for (const HammingKernel kernel : kKernels) {
    if (!HammingKernelAvailable(kernel)) continue;
    const HammingNearest nearest = FindHammingNearest(query, train, kernel);
    SCOPED_TRACE(static_cast<int>(kernel));
    EXPECT_EQ(nearest.best[0], 1);
    EXPECT_EQ(nearest.best_d[0], 0);
    EXPECT_EQ(nearest.second_d[0], 1);
    EXPECT_EQ(nearest.best[1], 0);
    EXPECT_EQ(nearest.best_d[1], 2);
    EXPECT_EQ(nearest.second_d[1], 8);
    EXPECT_EQ(nearest.best_query_of_train, (std::vector<int>{1, 0, 0}));
    EXPECT_EQ(nearest.best_query_d, (std::vector<int>{2, 0, 1}));
  }
}

TEST(FindHammingNearest, OneTrainDescriptorHasNoSecond) {
  std::mt19937 rng(3);
  const cv::Mat query = Descriptors(5, 32, &rng, 9), train = Descriptors(1, 32, &rng, 9);
  for (const HammingKernel kernel : kKernels) {
    if (!HammingKernelAvailable(kernel)) continue;
    const HammingNearest nearest = FindHammingNearest(query, train, kernel);
    for (int i = 0; i < 5; ++i) {
      EXPECT_EQ(nearest.best[i], 0);
      EXPECT_EQ(nearest.second_d[i], kNone);
    }
  }
}

TEST(FindHammingNearest, EmptySetsGiveNoNeighbours) {
  const cv::Mat empty(0, 32, CV_8U), some = cv::Mat::zeros(4, 32, CV_8U);
  for (const HammingKernel kernel : kKernels) {
    if (!HammingKernelAvailable(kernel)) continue;
    const HammingNearest to_empty = FindHammingNearest(some, empty, kernel);
    EXPECT_EQ(to_empty.best, (std::vector<int>(4, -1)));
    EXPECT_EQ(to_empty.second_d, (std::vector<int>(4, kNone)));
    const HammingNearest from_empty = FindHammingNearest(empty, some, kernel);
    EXPECT_EQ(from_empty.best_query_of_train, (std::vector<int>(4, -1)));
  }
}

// Every kernel this CPU has gives the portable scan's answer, index for index, for every descriptor length and
// for train sets that fill the vector blocks (4, 8 or 16 descriptors) exactly or not.
TEST(FindHammingNearest, EveryKernelAgreesWithThePortableScan) {
  std::mt19937 rng(7);
  int compared = 0;
  for (const int bytes : {8, 16, 24, 32}) {
    for (const int train_rows : {1, 2, 3, 4, 5, 7, 8, 9, 15, 16, 17, 32, 33, 48, 257}) {
      for (const int distinct : {3, 9}) {
        const cv::Mat query = Descriptors(40, bytes, &rng, distinct);
        const cv::Mat train = Descriptors(train_rows, bytes, &rng, distinct);
        const HammingNearest expected = FindHammingNearest(query, train, HammingKernel::kPortable);
        for (const HammingKernel kernel : kKernels) {
          if (!HammingKernelAvailable(kernel)) continue;
          SCOPED_TRACE(testing::Message() << "kernel " << static_cast<int>(kernel) << ", " << bytes << " bytes, "
                                          << train_rows << " train rows");
          const HammingNearest nearest = FindHammingNearest(query, train, kernel);
          EXPECT_EQ(nearest.best, expected.best);
          EXPECT_EQ(nearest.best_d, expected.best_d);
          EXPECT_EQ(nearest.second_d, expected.second_d);
          EXPECT_EQ(nearest.best_query_of_train, expected.best_query_of_train);
          EXPECT_EQ(nearest.best_query_d, expected.best_query_d);
          ++compared;
        }
      }
    }
  }
  EXPECT_GE(compared, 4 * 15 * 2 * 2);  // at least the portable and the automatic choice
}

TEST(FindHammingNearest, AKernelTheCpuLacksIsRefused) {
  const cv::Mat some = cv::Mat::zeros(2, 32, CV_8U);
  for (const HammingKernel kernel : kKernels) {
    if (HammingKernelAvailable(kernel)) continue;
    EXPECT_THROW(FindHammingNearest(some, some, kernel), std::invalid_argument);
  }
  EXPECT_TRUE(HammingKernelAvailable(BestHammingKernel()));
}

}  // namespace
}  // namespace retrace
