#include "retrace/feature/binary_features.h"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "retrace/feature/synthetic_texture.h"

namespace retrace {
namespace {

// The fraction of `matches` that follow the affine `transform` (2x3, a -> b) within `tolerance` pixels.
double FractionFollowing(const WideBaselineFeatures& fa, const WideBaselineFeatures& fb,
                         const std::vector<cv::DMatch>& matches, const cv::Mat& transform, double tolerance) {
  int correct = 0;
  for (const cv::DMatch& m : matches) {
    const cv::Point2f p = fa.keypoints[m.queryIdx].pt;
    const cv::Point2d expected(
        transform.at<double>(0, 0) * p.x + transform.at<double>(0, 1) * p.y + transform.at<double>(0, 2),
        transform.at<double>(1, 0) * p.x + transform.at<double>(1, 1) * p.y + transform.at<double>(1, 2));
    if (cv::norm(cv::Point2d(fb.keypoints[m.trainIdx].pt) - expected) < tolerance) ++correct;
  }
  return matches.empty() ? 0.0 : static_cast<double>(correct) / matches.size();
}

TEST(BinaryFeatures, MatchesFollowAKnownScaleAndShiftUnderOtherLight) {
  const cv::Mat a = ClutteredTexture(320, 240, 7);
  // b: a scaled by 1.15 about the centre (the camera drove closer), shifted, darker and with less contrast.
  cv::Mat transform = cv::getRotationMatrix2D(cv::Point2f(160, 120), 0.0, 1.15);
  transform.at<double>(0, 2) += 9.0;
  transform.at<double>(1, 2) -= 4.0;
  cv::Mat warped, b;
  cv::warpAffine(a, warped, transform, a.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(128));
  warped.convertTo(b, CV_8U, 0.7, 15.0);

  const BinaryFeatureOptions options;
  const WideBaselineFeatures fa = ExtractBinaryFeatures(a, options);
  const WideBaselineFeatures fb = ExtractBinaryFeatures(b, options);
  EXPECT_EQ(fa.descriptors.type(), CV_8U);
  EXPECT_EQ(fa.descriptors.cols, options.descriptor_bytes);
  EXPECT_EQ(fa.descriptors.rows, static_cast<int>(fa.size()));
  EXPECT_LE(fa.size(), 1000u);
  EXPECT_GE(fa.size(), 500u);
  const std::vector<cv::DMatch> matches = MatchBinary(fa, fb, options);
  ASSERT_GE(matches.size(), 100u);
  EXPECT_GE(FractionFollowing(fa, fb, matches, transform, 3.0), 0.9) << matches.size() << " matches";
  // Every match is mutual (cross-check) and passes the ratio test: no key-point is used twice.
  std::vector<int> used(fb.size(), 0);
  for (const cv::DMatch& m : matches) EXPECT_EQ(++used[m.trainIdx], 1);
}

TEST(BinaryFeatures, ShorterDescriptorsAreTheLeadingBytesAndStillMatchTheRightPoints) {
  const cv::Mat a = ClutteredTexture(320, 240, 5);
  cv::Mat transform = cv::getRotationMatrix2D(cv::Point2f(160, 120), 0.0, 1.1);
  transform.at<double>(0, 2) -= 6.0;
  cv::Mat b;
  cv::warpAffine(a, b, transform, a.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(128));
  BinaryFeatureOptions full;
  full.descriptor_bytes = 32;
  const WideBaselineFeatures a32 = ExtractBinaryFeatures(a, full);
  for (const int bytes : {8, 16, 24}) {
    BinaryFeatureOptions options;
    options.descriptor_bytes = bytes;
    const WideBaselineFeatures fa = ExtractBinaryFeatures(a, options);
    const WideBaselineFeatures fb = ExtractBinaryFeatures(b, options);
    // The same key-points, each described by the first `bytes` bytes of its full descriptor.
    ASSERT_EQ(fa.size(), a32.size());
    ASSERT_EQ(fa.descriptors.cols, bytes);
    EXPECT_EQ(cv::norm(fa.descriptors, a32.descriptors.colRange(0, bytes), cv::NORM_INF), 0.0) << bytes;
    EXPECT_NE(options.Name(), full.Name());  // maps store the name: other widths are computed again
    // Hamming matching of every width (one to three 64-bit words) finds the warp.
    const std::vector<cv::DMatch> matches = MatchBinary(fa, fb, options);
    EXPECT_GE(matches.size(), 100u) << bytes;
    EXPECT_GE(FractionFollowing(fa, fb, matches, transform, 3.0), 0.9) << bytes << " bytes, " << matches.size();
  }
  BinaryFeatureOptions odd;
  odd.descriptor_bytes = 12;
  EXPECT_FALSE(odd.Check());
}

TEST(BinaryFeatures, DescribingTheExtractedKeyPointsAgainGivesTheirDescriptors) {
  const cv::Mat image = ClutteredTexture(320, 240, 11);
  for (const int bytes : {32, 16}) {
    BinaryFeatureOptions options;
    options.descriptor_bytes = bytes;
    const WideBaselineFeatures extracted = ExtractBinaryFeatures(image, options);
    ASSERT_GE(extracted.size(), 500u);
    // The key-points as given (position, size; level and angle recovered): the same descriptors, bit for bit.
    std::vector<cv::KeyPoint> keypoints;
    for (const cv::KeyPoint& k : extracted.keypoints) keypoints.emplace_back(k.pt, k.size);
    const cv::Mat described = DescribeBinaryKeyPoints(image, keypoints, options);
    ASSERT_EQ(described.rows, extracted.descriptors.rows);
    ASSERT_EQ(described.cols, bytes);
    EXPECT_EQ(cv::norm(described, extracted.descriptors, cv::NORM_HAMMING), 0.0);
    // As a map stores them (1/8 px) on the image after a lossy codec: a few bits of 8 x bytes differ.
    std::vector<cv::KeyPoint> rounded;
    for (const cv::KeyPoint& k : keypoints) {
      rounded.emplace_back(cv::Point2f(std::round(8 * k.pt.x) / 8, std::round(8 * k.pt.y) / 8),
                           std::round(8 * k.size) / 8);
    }
    std::vector<uint8_t> jpeg;
    cv::imencode(".jpg", image, jpeg, {cv::IMWRITE_JPEG_QUALITY, 90});
    const cv::Mat stored = DescribeBinaryKeyPoints(cv::imdecode(jpeg, cv::IMREAD_GRAYSCALE), rounded, options);
    double bits = 0.0;
    for (int i = 0; i < stored.rows; ++i)
      bits += cv::norm(stored.row(i), extracted.descriptors.row(i), cv::NORM_HAMMING);
    EXPECT_LT(bits / stored.rows, 0.05 * 8 * bytes);
  }
  // A key-point too near the border to be described: a row of zeros, the others in place.
  const std::vector<cv::KeyPoint> edge = {cv::KeyPoint(160, 120, 31), cv::KeyPoint(2, 2, 31),
                                          cv::KeyPoint(100, 80, 37.2f)};
  const cv::Mat described = DescribeBinaryKeyPoints(image, edge);
  ASSERT_EQ(described.rows, 3);
  EXPECT_EQ(cv::countNonZero(described.row(1)), 0);
  EXPECT_GT(cv::countNonZero(described.row(0)), 0);
  EXPECT_GT(cv::countNonZero(described.row(2)), 0);
  EXPECT_EQ(DescribeBinaryKeyPoints(image, {}).rows, 0);
}

TEST(BinaryFeatures, OtherPlacesGiveFewMatches) {
  const BinaryFeatureOptions options;
  const WideBaselineFeatures fa = ExtractBinaryFeatures(ClutteredTexture(320, 240, 1), options);
  const WideBaselineFeatures fb = ExtractBinaryFeatures(ClutteredTexture(320, 240, 2), options);
  // Chance matches pass the ratio test rarely (a geometric verification rejects the rest).
  EXPECT_LT(MatchBinary(fa, fb, options).size(), 0.1 * fa.size());
}

TEST(BinaryFeatures, KeyPointsScaleWithTheImageOnlyWhenAskedAndBlankImagesHaveNone) {
  BinaryFeatureOptions options;
  const cv::Mat large_image = ClutteredTexture(1280, 960, 3);
  EXPECT_EQ(ExtractBinaryFeatures(large_image, options).size(), 1000u);  // a stored key-image: max_keypoints
  options.scale_with_area = true;
  const WideBaselineFeatures small = ExtractBinaryFeatures(ClutteredTexture(320, 240, 3), options);
  const WideBaselineFeatures large = ExtractBinaryFeatures(large_image, options);
  EXPECT_GT(large.size(), 1.5 * small.size());
  EXPECT_GT(large.size(), 1000u);
  EXPECT_LE(large.size(), 4000u);  // 1000 * sqrt(area ratio 16) at most
  const WideBaselineFeatures blank = ExtractBinaryFeatures(cv::Mat(240, 320, CV_8U, cv::Scalar(90)), options);
  EXPECT_EQ(blank.size(), 0u);
  EXPECT_EQ(blank.descriptors.type(), CV_8U);
  EXPECT_EQ(blank.descriptors.cols, options.descriptor_bytes);
  EXPECT_TRUE(MatchBinary(blank, small, options).empty());
}

TEST(BinaryFeatures, RejectsBadOptions) {
  BinaryFeatureOptions options;
  EXPECT_TRUE(options.Check());
  options.patch_size = 3;
  std::string error;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("patch_size"), std::string::npos);
  EXPECT_THROW(ExtractBinaryFeatures(ClutteredTexture(64, 48, 1), options), std::invalid_argument);
  EXPECT_NE(BinaryFeatureOptions().Name(), options.Name());
}

}  // namespace
}  // namespace retrace
