#include "retrace/feature/corner_detector.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>
#include <vector>

namespace retrace {
namespace {

// Dark image with bright axis-aligned rectangles: every rectangle corner is a corner with a known position.
cv::Mat RectanglesImage(std::vector<Vector2d>* corners) {
  cv::Mat image(240, 320, CV_8UC1, cv::Scalar(40));
  const std::vector<cv::Rect> rects = {
      {40, 40, 50, 30}, {150, 60, 40, 60}, {230, 150, 50, 40}, {60, 150, 70, 50}};
  for (const cv::Rect& r : rects) {
    cv::rectangle(image, r, cv::Scalar(200), cv::FILLED);
    // Pixel centres of the corner pixels: the corner lies between the last inside and first outside pixel.
    corners->emplace_back(r.x - 0.5, r.y - 0.5);
    corners->emplace_back(r.x + r.width - 0.5, r.y - 0.5);
    corners->emplace_back(r.x - 0.5, r.y + r.height - 0.5);
    corners->emplace_back(r.x + r.width - 0.5, r.y + r.height - 0.5);
  }
  return image;
}

double NearestDistance(const Vector2d& p, const std::vector<Vector2d>& points) {
  double best = 1e9;
  for (const Vector2d& q : points) best = std::min(best, (p - q).norm());
  return best;
}

TEST(CornerDetector, FindsRectangleCornersWithMinimumDistance) {
  std::vector<Vector2d> truth;
  const ImagePyramid pyramid(RectanglesImage(&truth));
  CornerDetectorOptions options;
  options.max_corners = 100;
  options.min_distance = 10.0;
  options.quality_level = 0.1;
  const std::vector<Corner> corners = DetectCorners(pyramid, options);
  // Every true corner is found within 2.5 px (the minimum-eigenvalue maximum of a sharp corner lies ~1.5 px
  // inside), and nothing else (edges and flat areas are not corners).
  for (const Vector2d& t : truth) {
    std::vector<Vector2d> found;
    for (const Corner& c : corners) found.push_back(c.position);
    EXPECT_LT(NearestDistance(t, found), 2.5) << "corner " << t.transpose();
  }
  EXPECT_EQ(corners.size(), truth.size());
  for (size_t i = 0; i < corners.size(); ++i) {
    EXPECT_LT(NearestDistance(corners[i].position, truth), 2.5);
    EXPECT_GT(corners[i].score, 0.0);
    EXPECT_LE(corners[i].score, 1.0);
    for (size_t j = 0; j < i; ++j) EXPECT_GE((corners[i].position - corners[j].position).norm(), 10.0);
  }
}

TEST(CornerDetector, RespectsMaskExistingPointsAndLimit) {
  std::vector<Vector2d> truth;
  const ImagePyramid pyramid(RectanglesImage(&truth));
  CornerDetectorOptions options;
  options.quality_level = 0.1;
  // Mask: left half only.
  cv::Mat mask(240, 320, CV_8UC1, cv::Scalar(0));
  mask(cv::Rect(0, 0, 140, 240)).setTo(255);
  // An already tracked point on the corner (40, 40) region.
  const std::vector<Vector2d> existing = {Vector2d(39.5, 39.5)};
  const std::vector<Corner> corners = DetectCorners(pyramid, options, mask, existing);
  int expected = 0;
  for (const Vector2d& t : truth) expected += t.x() < 140 && (t - existing[0]).norm() >= options.min_distance;
  EXPECT_EQ(static_cast<int>(corners.size()), expected);
  for (const Corner& c : corners) {
    EXPECT_LT(c.position.x(), 140.0);
    EXPECT_GE((c.position - existing[0]).norm(), options.min_distance);
  }
  options.max_corners = 3;
  EXPECT_EQ(DetectCorners(pyramid, options).size(), 3u);
}

TEST(CornerDetector, MultiScaleFindsBlurredCornersOnCoarseLevel) {
  // A sharp small square on the left, a strongly blurred large square on the right: at level 0 the blurred
  // corners respond far below the sharp ones; on the coarse levels they are found, and reported in level-0
  // pixels.
  cv::Mat blurred(240, 320, CV_8UC1, cv::Scalar(40));
  cv::rectangle(blurred, cv::Rect(160, 60, 120, 120), cv::Scalar(200), cv::FILLED);
  cv::GaussianBlur(blurred, blurred, cv::Size(0, 0), 5.0);
  cv::Mat image = blurred.clone();
  cv::rectangle(image, cv::Rect(40, 100, 30, 30), cv::Scalar(220), cv::FILLED);
  const std::vector<Vector2d> blurred_corners = {
      {159.5, 59.5}, {279.5, 59.5}, {159.5, 179.5}, {279.5, 179.5}};
  const ImagePyramid pyramid(image);
  CornerDetectorOptions options;
  options.quality_level = 0.1;
  options.min_distance = 20.0;
  options.num_scales = 1;
  for (const Corner& c : DetectCorners(pyramid, options)) {
    EXPECT_GT(NearestDistance(c.position, blurred_corners), 20.0) << "level 0 alone finds a blurred corner";
  }
  options.num_scales = 3;
  int found = 0;
  for (const Corner& c : DetectCorners(pyramid, options)) {
    // The response maximum of a corner blurred with sigma = 5 px lies about 1.7 sigma inside the corner (8.5
    // px here).
    if (NearestDistance(c.position, blurred_corners) < 14.0) {
      ++found;
      EXPECT_GT(c.level, 0);
    }
  }
  EXPECT_EQ(found, 4);
}

TEST(ImagePyramid, LevelsAndCoordinateConvention) {
  cv::Mat image(240, 320, CV_8UC1, cv::Scalar(0));
  cv::circle(image, cv::Point(161, 101), 6, cv::Scalar(255), cv::FILLED);
  const ImagePyramid pyramid(image);
  ASSERT_EQ(pyramid.NumLevels(), 3);
  EXPECT_EQ(pyramid.Level(1).cols, 160);
  EXPECT_EQ(pyramid.Level(2).rows, 60);
  EXPECT_EQ(pyramid.Level(0).type(), CV_32FC1);
  // The blob centroid at level l is the level-0 centroid divided by 2^l.
  for (int level = 0; level < 3; ++level) {
    const cv::Moments m = cv::moments(pyramid.Level(level));
    EXPECT_NEAR(m.m10 / m.m00, 161.0 / (1 << level), 0.05) << "level " << level;
    EXPECT_NEAR(m.m01 / m.m00, 101.0 / (1 << level), 0.05) << "level " << level;
  }
  EXPECT_THROW(ImagePyramid(cv::Mat()), std::invalid_argument);
  EXPECT_THROW(ImagePyramid(cv::Mat(10, 10, CV_8UC3)), std::invalid_argument);
}

}  // namespace
}  // namespace retrace
