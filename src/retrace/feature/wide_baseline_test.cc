#include "retrace/feature/wide_baseline.h"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "retrace/feature/synthetic_texture.h"

namespace retrace {
namespace {

TEST(WideBaseline, MatchesFollowAKnownSimilarityTransform) {
  const cv::Mat a = ClutteredTexture(640, 480, 7);
  // b = a rotated by 8 degrees, scaled by 1.3 about the centre, then shifted.
  cv::Mat transform = cv::getRotationMatrix2D(cv::Point2f(320, 240), 8.0, 1.3);
  transform.at<double>(0, 2) += 15.0;
  transform.at<double>(1, 2) -= 10.0;
  cv::Mat b;
  cv::warpAffine(a, b, transform, a.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(128));

  WideBaselineOptions options;
  options.upright = false;  // the image is rolled: orientation-invariant descriptors
  const WideBaselineFeatures fa = ExtractWideBaselineFeatures(a, options);
  const WideBaselineFeatures fb = ExtractWideBaselineFeatures(b, options);
  const std::vector<cv::DMatch> matches = MatchWideBaseline(fa, fb, options);
  ASSERT_GE(matches.size(), 100u);
  int correct = 0;
  for (const cv::DMatch& m : matches) {
    const cv::Point2f p = fa.keypoints[m.queryIdx].pt;
    const cv::Point2d expected(transform.at<double>(0, 0) * p.x + transform.at<double>(0, 1) * p.y +
                                   transform.at<double>(0, 2),
                               transform.at<double>(1, 0) * p.x + transform.at<double>(1, 1) * p.y +
                                   transform.at<double>(1, 2));
    if (cv::norm(cv::Point2d(fb.keypoints[m.trainIdx].pt) - expected) < 3.0) ++correct;
  }
  EXPECT_GE(correct, 0.95 * matches.size()) << correct << " of " << matches.size();
}

TEST(WideBaseline, EveryDetectorContributesAndFusionRemovesDuplicates) {
  const cv::Mat image = ClutteredTexture(640, 480, 3);
  const WideBaselineOptions options;
  const WideBaselineFeatures features = ExtractWideBaselineFeatures(image, options);
  int per_detector[3] = {0, 0, 0};
  for (const cv::KeyPoint& k : features.keypoints) ++per_detector[k.class_id];
  EXPECT_GT(per_detector[0], 50);
  EXPECT_GT(per_detector[1], 50);
  EXPECT_GT(per_detector[2], 10);
  ASSERT_EQ(features.descriptors.rows, static_cast<int>(features.keypoints.size()));
  for (size_t i = 0; i < features.keypoints.size(); ++i) {
    for (size_t j = i + 1; j < features.keypoints.size(); ++j) {
      const cv::KeyPoint& a = features.keypoints[i];
      const cv::KeyPoint& b = features.keypoints[j];
      if (a.class_id == b.class_id) continue;  // fusion acts between detectors
      const float ratio = std::max(a.size, b.size) / std::min(a.size, b.size);
      EXPECT_FALSE(cv::norm(a.pt - b.pt) < options.fusion_radius_px && ratio < 2.0f) << i << " " << j;
    }
  }
}

// Features with hand-made descriptors: descriptor i is e_0 * values[i] (128-D), so L2 distances are known.
WideBaselineFeatures FeaturesWithDescriptors(const std::vector<float>& values) {
  WideBaselineFeatures features;
  features.descriptors = cv::Mat::zeros(static_cast<int>(values.size()), 128, CV_32F);
  for (size_t i = 0; i < values.size(); ++i) {
    features.keypoints.emplace_back(cv::Point2f(10.0f * i, 0.0f), 8.0f);
    features.descriptors.at<float>(static_cast<int>(i), 0) = values[i];
  }
  return features;
}

TEST(WideBaseline, RatioTestKeepsOnlyDistinctiveMatches) {
  // Query descriptors 0 and 100. Train: 1 and 10 (for query 0: distances 1 and 10, ratio 0.1: kept),
  // 95 and 104 (for query 100: distances 5 and 4, ratio 0.8: ambiguous, rejected by 0.6 but kept by 0.9).
  const WideBaselineFeatures query = FeaturesWithDescriptors({0.0f, 100.0f});
  const WideBaselineFeatures train = FeaturesWithDescriptors({1.0f, 10.0f, 95.0f, 104.0f});
  WideBaselineOptions options;
  options.cross_check = false;
  std::vector<cv::DMatch> matches = MatchWideBaseline(query, train, options);
  ASSERT_EQ(matches.size(), 1u);
  EXPECT_EQ(matches[0].queryIdx, 0);
  EXPECT_EQ(matches[0].trainIdx, 0);
  options.ratio = 0.9;
  matches = MatchWideBaseline(query, train, options);
  ASSERT_EQ(matches.size(), 2u);
  EXPECT_EQ(matches[1].trainIdx, 3);  // 104 is nearer to 100 than 95
}

TEST(WideBaseline, CrossCheckDropsOneSidedMatches) {
  // Train 5 is the best match of query 0 (distance 5) but query 6 is closer to it (distance 1).
  const WideBaselineFeatures query = FeaturesWithDescriptors({0.0f, 6.0f, 200.0f});
  const WideBaselineFeatures train = FeaturesWithDescriptors({5.0f, 100.0f});
  WideBaselineOptions options;
  options.ratio = 1.0;
  options.cross_check = true;
  const std::vector<cv::DMatch> matches = MatchWideBaseline(query, train, options);
  for (const cv::DMatch& m : matches) EXPECT_NE(m.queryIdx, 0);
  ASSERT_FALSE(matches.empty());
  EXPECT_EQ(matches[0].queryIdx, 1);
}

TEST(WideBaseline, RatioTestThinsOutRepeatedStructure) {
  // A facade of identical windows: most key-points have an equally good copy in the other image.
  const cv::Mat facade = [] {
    cv::Mat repeated;
    cv::repeat(ClutteredTexture(40, 40, 11), 8, 12, repeated);
    return repeated;
  }();
  cv::Mat shifted;
  const cv::Mat shift = (cv::Mat_<double>(2, 3) << 1, 0, 3.0, 0, 1, 2.0);
  cv::warpAffine(facade, shifted, shift, facade.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);
  const WideBaselineOptions strict;
  WideBaselineOptions loose = strict;
  loose.ratio = 1.0;
  loose.cross_check = false;
  const auto fa = ExtractWideBaselineFeatures(facade, strict);
  const auto fb = ExtractWideBaselineFeatures(shifted, strict);
  const size_t strict_matches = MatchWideBaseline(fa, fb, strict).size();
  const size_t loose_matches = MatchWideBaseline(fa, fb, loose).size();
  ASSERT_GT(loose_matches, 100u);
  EXPECT_LT(strict_matches, loose_matches / 2) << strict_matches << " vs " << loose_matches;
}

TEST(WideBaseline, BlankImageGivesNoFeaturesAndNoMatches) {
  const cv::Mat blank(240, 320, CV_8UC1, cv::Scalar(90));
  const auto features = ExtractWideBaselineFeatures(blank);
  EXPECT_EQ(features.size(), 0u);
  EXPECT_TRUE(MatchWideBaseline(features, features).empty());
}

}  // namespace
}  // namespace retrace
