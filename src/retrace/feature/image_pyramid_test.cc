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

// The 8-bit input is smoothed straight into float (ImagePyramid::Build): every level must be the one built from the
// same image converted to float first, bit for bit, whatever the size (vector blocks and scalar tails) and the kernel.
TEST(ImagePyramid, EightBitInputGivesTheFloatInputsLevels) {
  cv::RNG rng(7);
  for (const cv::Size size : {cv::Size(1226, 370), cv::Size(320, 240), cv::Size(333, 97), cv::Size(17, 13)}) {
    cv::Mat image(size, CV_8UC1);
    rng.fill(image, cv::RNG::UNIFORM, 0, 256);
    cv::Mat as_float;
    image.convertTo(as_float, CV_32F);
    for (const double sigma : {0.0, 0.5, 0.7, 1.1, 2.68, 4.0}) {  // 1 (none), 5, 7, 9, 19 and 25 taps
      ImagePyramidOptions options;
      options.num_levels = 3;
      options.smoothing_sigma = sigma;
      const ImagePyramid from_bytes(image, options), from_floats(as_float, options);
      ASSERT_EQ(from_bytes.NumLevels(), from_floats.NumLevels());
      for (int level = 0; level < from_bytes.NumLevels(); ++level) {
        ASSERT_EQ(from_bytes.Level(level).type(), CV_32FC1);
        EXPECT_EQ(cv::norm(from_bytes.Level(level), from_floats.Level(level), cv::NORM_INF), 0.0)
            << size << " sigma " << sigma << " level " << level;
      }
    }
  }
}

}  // namespace
}  // namespace retrace
