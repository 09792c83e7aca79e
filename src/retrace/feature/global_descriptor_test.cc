#include "retrace/feature/global_descriptor.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <cstdio>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "retrace/feature/synthetic_texture.h"
#include "retrace/util/testing.h"

namespace retrace {
namespace {

cv::Mat Texture(int width, int height, uint64_t seed) {
  SyntheticTextureOptions options;
  options.width = width;
  options.height = height;
  options.num_shapes = width * height / 400;
  options.seed = seed;
  cv::Mat image;
  SyntheticTexture(options).Render(width, height).convertTo(image, CV_8U);
  return image;
}

TEST(GlobalDescriptor, SameImageIsAtDistanceZero) {
  const cv::Mat image = Texture(320, 240, 1);
  const GlobalDescriptor d = ComputeGlobalDescriptor(image);
  EXPECT_EQ(d.thumbnail.cols, 48);
  EXPECT_EQ(d.thumbnail.rows, 36);
  EXPECT_DOUBLE_EQ(GlobalDescriptorDistance(d, d), 0.0);
}

TEST(GlobalDescriptor, IgnoresBrightnessAndSmallShiftsButNotOtherPlaces) {
  const cv::Mat image = Texture(360, 240, 2);
  const cv::Mat other = Texture(360, 240, 3);
  // The same place, darker, with less contrast, and seen 12 px (1.6 thumbnail pixels) further to the right.
  cv::Mat changed;
  image.convertTo(changed, CV_8U, 0.6, 20.0);
  const cv::Mat place = image.colRange(0, 320);
  const cv::Mat revisit = changed.colRange(12, 332);

  const GlobalDescriptor d_place = ComputeGlobalDescriptor(place);
  const double same = GlobalDescriptorDistance(d_place, ComputeGlobalDescriptor(revisit));
  const double different = GlobalDescriptorDistance(d_place, ComputeGlobalDescriptor(other.colRange(0, 320)));
  EXPECT_LT(same, 0.35);
  EXPECT_GT(different, 0.8);

  // Without shifts the revisit looks far less alike.
  GlobalDescriptorOptions no_shift;
  no_shift.max_shift = 0;
  EXPECT_GT(GlobalDescriptorDistance(ComputeGlobalDescriptor(place, no_shift),
                                     ComputeGlobalDescriptor(revisit, no_shift), no_shift),
            same + 0.2);
}

TEST(GlobalDescriptor, RankPutsTheSamePlaceFirst) {
  std::vector<GlobalDescriptor> database;
  for (uint64_t seed = 10; seed < 20; ++seed) database.push_back(ComputeGlobalDescriptor(Texture(320, 240, seed)));
  cv::Mat query;
  Texture(320, 240, 14).convertTo(query, CV_8U, 1.3, -10.0);
  const std::vector<size_t> order = RankByGlobalDescriptor(ComputeGlobalDescriptor(query), database);
  ASSERT_EQ(order.size(), database.size());
  EXPECT_EQ(order.front(), 4u);
}

TEST(GlobalDescriptor, RejectsBadOptionsAndInput) {
  GlobalDescriptorOptions options;
  options.patch_size = 4;
  EXPECT_FALSE(options.Check());
  EXPECT_THROW(ComputeGlobalDescriptor(Texture(64, 48, 1), options), std::invalid_argument);
  EXPECT_THROW(ComputeGlobalDescriptor(cv::Mat()), std::invalid_argument);
  const GlobalDescriptor wide = ComputeGlobalDescriptor(Texture(320, 100, 1));
  const GlobalDescriptor narrow = ComputeGlobalDescriptor(Texture(320, 240, 1));
  EXPECT_THROW(GlobalDescriptorDistance(wide, narrow), std::invalid_argument);
}

TEST(AppearanceIndex, QuantisedDistancesAreTheFloatOnes) {
  const GlobalDescriptor a = ComputeGlobalDescriptor(Texture(320, 240, 21));
  cv::Mat darker;
  Texture(320, 240, 21).colRange(8, 320).convertTo(darker, CV_8U, 0.7, 12.0);
  cv::Mat shifted;
  cv::resize(darker, shifted, cv::Size(320, 240), 0, 0, cv::INTER_LINEAR);
  const std::vector<GlobalDescriptor> others = {ComputeGlobalDescriptor(shifted),
                                                ComputeGlobalDescriptor(Texture(320, 240, 22)), a};
  AppearanceIndex index;
  for (const GlobalDescriptor& d : others) index.Add(QuantizeGlobalDescriptor(d));
  ASSERT_EQ(index.size(), 3u);
  const cv::Mat query = QuantizeGlobalDescriptor(a);
  EXPECT_EQ(query.type(), CV_8U);
  EXPECT_EQ(query.size(), a.thumbnail.size());
  for (size_t i = 0; i < others.size(); ++i) {
    // Quantisation steps of 1/32 and clamping at ±4 σ change a mean absolute difference by a few hundredths.
    EXPECT_NEAR(index.Distance(query, i), GlobalDescriptorDistance(a, others[i]), 0.03) << i;
  }
  EXPECT_DOUBLE_EQ(index.Distance(query, 2), 0.0);
  // Dequantised values are the float ones to within half a step (inside ±4 σ).
  const GlobalDescriptor back = DequantizeGlobalDescriptor(query);
  cv::Mat clipped = cv::min(cv::max(a.thumbnail, -4.0), 127.0 / 32.0);
  EXPECT_LE(cv::norm(back.thumbnail, clipped, cv::NORM_INF), 1.0 / 64.0 + 1e-6);
}

TEST(AppearanceIndex, RanksASubsetAsRankByGlobalDescriptor) {
  std::vector<GlobalDescriptor> database;
  AppearanceIndex index;
  for (uint64_t seed = 30; seed < 42; ++seed) {
    database.push_back(ComputeGlobalDescriptor(Texture(320, 240, seed)));
    index.Add(QuantizeGlobalDescriptor(database.back()));
  }
  cv::Mat query_image;
  Texture(320, 240, 37).convertTo(query_image, CV_8U, 1.2, -5.0);
  const GlobalDescriptor query = ComputeGlobalDescriptor(query_image);
  const std::vector<size_t> all = RankByGlobalDescriptor(query, database);
  std::vector<size_t> every(database.size());
  std::iota(every.begin(), every.end(), 0);
  const std::vector<size_t> ranked = index.Rank(QuantizeGlobalDescriptor(query), every);
  ASSERT_EQ(ranked.size(), all.size());
  EXPECT_EQ(ranked.front(), 7u);
  EXPECT_EQ(all.front(), 7u);
  // A subset is ranked among itself and returned as indices of the index.
  const std::vector<size_t> subset = index.Rank(QuantizeGlobalDescriptor(query), {2, 7, 9});
  ASSERT_EQ(subset.size(), 3u);
  EXPECT_EQ(subset.front(), 7u);
  EXPECT_THROW(index.Add(QuantizeGlobalDescriptor(ComputeGlobalDescriptor(Texture(320, 100, 1)))),
               std::invalid_argument);
  EXPECT_THROW(index.Distance(QuantizeGlobalDescriptor(query), 99), std::out_of_range);
}

// KITTI 07: key-images every 10 frames of the even frames, queried with the odd frames between them, as the
// repeat's retrieval does. Ground truth: the two key-images that bracket the query frame.
TEST(GlobalDescriptor, KittiOddFramesFindTheirKeyImages) {
  RETRACE_REQUIRE_SHARED_DATA(kitti, "kitti07");
  const auto read = [&kitti](int frame) {
    char name[32];
    std::snprintf(name, sizeof(name), "image_0/%06d.png", frame);
    return cv::imread((kitti / name).string(), cv::IMREAD_GRAYSCALE);
  };
  std::vector<GlobalDescriptor> database;
  std::vector<int> key_frames;
  for (int frame = 0; frame < 160; frame += 10) {
    const cv::Mat image = read(frame);
    ASSERT_FALSE(image.empty()) << "frame " << frame;
    database.push_back(ComputeGlobalDescriptor(image));
    key_frames.push_back(frame);
  }
  int first = 0, queries = 0;
  size_t worst_rank = 0;
  for (int frame = 1; frame < 150; frame += 2) {
    const std::vector<size_t> order = RankByGlobalDescriptor(ComputeGlobalDescriptor(read(frame)), database);
    const auto brackets = [&](size_t k) { return key_frames[k] <= frame + 10 && key_frames[k] >= frame - 10; };
    size_t rank = 0;
    while (!brackets(order[rank])) ++rank;
    ++queries;
    first += rank == 0;
    worst_rank = std::max(worst_rank, rank + 1);
  }
  std::printf("kitti07: a bracketing key-image ranked first for %d of %d odd frames; worst rank %zu of %zu\n", first,
              queries, worst_rank, database.size());
  // Measured: 67 of 75 first (the others in the turns, frames 33-35, 95-103, 127-135), worst rank 3.
  EXPECT_GE(first, 0.85 * queries);
  EXPECT_LE(worst_rank, 3u);
}

}  // namespace
}  // namespace retrace
