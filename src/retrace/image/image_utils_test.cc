#include "retrace/image/image_utils.h"

#include <gtest/gtest.h>

namespace retrace {
namespace {

TEST(ImageUtils, ToGray8ConvertsChannelsAndDepths) {
  EXPECT_TRUE(ToGray8(cv::Mat()).empty());
  // BT.601: gray = 0.299 R + 0.587 G + 0.114 B; pure green 255 -> 149.7.
  const cv::Mat green(4, 5, CV_8UC3, cv::Scalar(0, 255, 0));
  cv::Mat gray = ToGray8(green);
  ASSERT_EQ(gray.type(), CV_8UC1);
  EXPECT_EQ(gray.size(), cv::Size(5, 4));
  EXPECT_EQ(gray.at<uint8_t>(2, 3), 150);
  const cv::Mat blue_alpha(4, 5, CV_8UC4, cv::Scalar(200, 0, 0, 7));
  EXPECT_EQ(ToGray8(blue_alpha).at<uint8_t>(0, 0), 23);  // 0.114 * 200 = 22.8
  const cv::Mat sixteen(3, 3, CV_16UC1, cv::Scalar(51200));
  EXPECT_EQ(ToGray8(sixteen).at<uint8_t>(1, 1), 200);  // 51200 / 256
  const cv::Mat unit(3, 3, CV_32FC1, cv::Scalar(0.25));
  EXPECT_EQ(ToGray8(unit).at<uint8_t>(1, 1), 64);  // 0.25 * 255 = 63.75
  // An 8-bit gray input is copied, not shared.
  cv::Mat input(2, 2, CV_8UC1, cv::Scalar(9));
  cv::Mat copy = ToGray8(input);
  input.setTo(1);
  EXPECT_EQ(copy.at<uint8_t>(0, 0), 9);
}

TEST(ImageUtils, ResizeToWidthKeepsAspectRatio) {
  cv::Mat out;
  EXPECT_DOUBLE_EQ(ResizeToWidth(cv::Mat(480, 640, CV_8UC1, cv::Scalar(5)), 320, &out), 0.5);
  EXPECT_EQ(out.size(), cv::Size(320, 240));
  EXPECT_EQ(out.at<uint8_t>(100, 100), 5);
  EXPECT_NEAR(ResizeToWidth(cv::Mat(370, 1226, CV_8UC1), 613, &out), 0.5, 1e-12);
  EXPECT_EQ(out.size(), cv::Size(613, 185));
  EXPECT_NEAR(ResizeToWidth(cv::Mat(370, 1226, CV_8UC1), 320, &out), 320.0 / 1226.0, 1e-12);
  EXPECT_EQ(out.size(), cv::Size(320, 97));  // 370 * 0.261 = 96.57
  EXPECT_DOUBLE_EQ(ResizeToWidth(cv::Mat(10, 20, CV_8UC1), 60, &out), 3.0);
  EXPECT_EQ(out.size(), cv::Size(60, 30));
  EXPECT_DOUBLE_EQ(ResizeToWidth(cv::Mat(10, 20, CV_8UC1), 0, &out), 1.0);
  EXPECT_EQ(out.size(), cv::Size(20, 10));
}

TEST(ImageUtils, ContactSheetLayoutAndLabels) {
  std::vector<cv::Mat> images;
  for (int i = 0; i < 5; ++i) images.emplace_back(60, 80, CV_8UC1, cv::Scalar(40 * i + 10));
  const std::vector<std::string> labels = {"zero", "", "two"};
  const cv::Mat sheet = MakeContactSheet(images, labels, 3, 100);
  // 3 columns, 2 rows of 100x75 thumbnails with 2-pixel gaps.
  ASSERT_EQ(sheet.type(), CV_8UC3);
  EXPECT_EQ(sheet.size(), cv::Size(3 * 102 + 2, 2 * 77 + 2));
  // Centre of thumbnail 4 (row 1, column 1) has its grey level.
  const cv::Vec3b centre = sheet.at<cv::Vec3b>(2 + 77 + 37, 2 + 102 + 50);
  EXPECT_EQ(centre, cv::Vec3b(170, 170, 170));
  // The labelled thumbnail 0 has yellow text pixels in its top-left corner; unlabelled thumbnail 1 has none.
  const auto count_yellow = [&](cv::Rect area) {
    int n = 0;
    for (int y = area.y; y < area.y + area.height; ++y) {
      for (int x = area.x; x < area.x + area.width; ++x) {
        const cv::Vec3b p = sheet.at<cv::Vec3b>(y, x);
        n += p[2] > 150 && p[1] > 150 && p[0] < 80;
      }
    }
    return n;
  };
  EXPECT_GT(count_yellow(cv::Rect(2, 2, 60, 20)), 10);
  EXPECT_EQ(count_yellow(cv::Rect(104, 2, 60, 20)), 0);
  EXPECT_TRUE(MakeContactSheet({}, {}, 3, 100).empty());
}

}  // namespace
}  // namespace retrace
