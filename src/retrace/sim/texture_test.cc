#include "retrace/sim/texture.h"

#include <cmath>

#include <gtest/gtest.h>

namespace retrace {
namespace {

// A 16 x 8 texture whose texel (x, y) has reflectance (x + 16 y) / 127 in all channels (a ramp, exact in 8 bits
// after the x 255 grey scaling only where it divides; compared with 1/255 tolerance).
cv::Mat Ramp() {
  cv::Mat image(8, 16, CV_32FC3);
  for (int y = 0; y < 8; ++y) {
    for (int x = 0; x < 16; ++x) image.at<cv::Vec3f>(y, x) = cv::Vec3f::all((x + 16.0f * y) / 127.0f);
  }
  return image;
}

TEST(TextureTest, BilinearHitsTexelCentresAndWrapsAround) {
  const Texture texture(Ramp());
  ASSERT_EQ(texture.width(), 16);
  ASSERT_EQ(texture.num_levels(), 5);  // 16x8, 8x4, 4x2, 2x1, 1x1
  // Texel (3, 2) has its centre at ((3 + 0.5) / 16, (2 + 0.5) / 8).
  const float u = 3.5f / 16, v = 2.5f / 8;
  EXPECT_NEAR(texture.SampleTrilinear(u, v, 0.0f).x(), 35.0f / 127, 1e-6f);
  EXPECT_NEAR(texture.SampleTrilinearGray(u, v, 0.0f), 35.0f / 127, 1.0f / 255);
  // Half way between texels (3, 2) and (4, 2).
  EXPECT_NEAR(texture.SampleTrilinear(4.0f / 16, v, 0.0f).x(), 35.5f / 127, 1e-6f);
  // Repeats with period 1; the left border blends the last and the first column of the row.
  EXPECT_NEAR(texture.SampleTrilinear(u + 3.0f, v - 2.0f, 0.0f).x(), 35.0f / 127, 1e-5f);
  EXPECT_NEAR(texture.SampleTrilinear(0.0f, v, 0.0f).x(), (32.0f + 47.0f) / 2 / 127, 1e-6f);
  EXPECT_NEAR(texture.SampleTrilinear(-1e-7f, v, 0.0f).x(), texture.SampleTrilinear(1e-7f, v, 0.0f).x(), 1e-4f);
  EXPECT_NEAR(texture.SampleTrilinearGray(-1e-7f, v, 0.0f), texture.SampleTrilinearGray(1e-7f, v, 0.0f), 1e-4f);
}

TEST(TextureTest, LargeFootprintsAverageAndAnisotropicOnesStaySharpAcross) {
  const Texture texture(Ramp());
  const float mean = 63.5f / 127;
  EXPECT_NEAR(texture.Mean().x(), mean, 1e-5f);
  // A footprint covering the texture many times: the mean.
  EXPECT_NEAR(texture.SampleFiltered(0.3f, 0.6f, Vector2f(40, 0), Vector2f(0, 40)).x(), mean, 1e-5f);
  EXPECT_NEAR(texture.SampleFilteredGray(0.3f, 0.6f, Vector2f(40, 0), Vector2f(0, 40)), mean, 1.0f / 255);
  // One row wide, the whole width long (along u): the mean of that row (x + 16 y averaged over x), not of the
  // texture. Row 5: (7.5 + 80) / 127.
  const float v = 5.5f / 8;
  const float row = (7.5f + 80.0f) / 127;
  const float along = texture.SampleFiltered(0.5f, v, Vector2f(1.0f, 0), Vector2f(0, 1.0f / 8)).x();
  EXPECT_NEAR(along, row, 1.5f / 127);  // 4 taps on level 2 (4 texels wide): the row, blurred by a few texels
  EXPECT_GT(std::abs(along - mean), 10.0f / 127);
  // Zero footprint: the bilinear level-0 lookup.
  EXPECT_FLOAT_EQ(texture.SampleFiltered(0.2f, 0.3f, Vector2f::Zero(), Vector2f::Zero()).x(),
                  texture.SampleTrilinear(0.2f, 0.3f, 0.0f).x());
}

}  // namespace
}  // namespace retrace
