#include "retrace/feature/image_pyramid.h"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

namespace retrace {
namespace {

TEST(ImagePyramid, FinestLevelsShareTheImageData) {
  cv::Mat image(64, 80, CV_8UC1);
  cv::randu(image, 0, 255);
  ImagePyramidOptions options;
  options.num_levels = 3;
  const ImagePyramid pyramid(image, options);
  const ImagePyramid finest = pyramid.FinestLevels(2);
  ASSERT_EQ(finest.NumLevels(), 2);
  EXPECT_EQ(finest.Options().num_levels, 2);
  for (int level = 0; level < 2; ++level) EXPECT_EQ(finest.Level(level).data, pyramid.Level(level).data);
  EXPECT_EQ(pyramid.FinestLevels(0).NumLevels(), 1);
  EXPECT_EQ(pyramid.FinestLevels(10).NumLevels(), 3);
  EXPECT_TRUE(ImagePyramid().FinestLevels(2).Empty());
}

}  // namespace
}  // namespace retrace
