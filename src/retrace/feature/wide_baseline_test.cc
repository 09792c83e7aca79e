#include "retrace/feature/wide_baseline.h"

#include <gtest/gtest.h>
#include <Eigen/Geometry>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "retrace/feature/synthetic_texture.h"
#include "retrace/geometry/essential.h"

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

// Two cameras looking at the same points: camera t is camera q moved 1 unit to the right and turned by 5 degrees
// about the vertical. Each point has a random 32-byte descriptor, seen in t with 8 of its bits flipped; t also sees
// a copy of every descriptor (6 bits flipped) at a bearing far from the point's epipolar plane — texture repeated
// elsewhere in the image, which makes the global ratio test refuse the right match.
struct EpipolarScene {
  WideBaselineFeatures query, train;
  std::vector<Eigen::Vector3d> query_bearings, train_bearings;
  Rigid3d t_from_q;
  int points = 0;  // train key-point i < points is query key-point i's true match
};

EpipolarScene MakeEpipolarScene(int points, uint64_t seed) {
  EpipolarScene scene;
  scene.points = points;
  cv::RNG rng(seed);
  const double angle = 5.0 * M_PI / 180.0;
  const Matrix3d rotation = Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitY()).toRotationMatrix();
  scene.t_from_q = Rigid3d(rotation, -rotation * Eigen::Vector3d(1.0, 0.0, 0.0));  // t's centre at x = 1 in q's frame
  scene.query.descriptors = cv::Mat(points, 32, CV_8U);
  scene.train.descriptors = cv::Mat(2 * points, 32, CV_8U);
  rng.fill(scene.query.descriptors, cv::RNG::UNIFORM, 0, 256);
  const auto flip_bits = [&rng](cv::Mat row, int bits) {
    for (int k = 0; k < bits; ++k) {
      const int bit = rng.uniform(0, 256);
      row.at<uchar>(0, bit / 8) ^= static_cast<uchar>(1 << (bit % 8));
    }
  };
  scene.train_bearings.resize(2 * points);
  for (int i = 0; i < points; ++i) {
    const Eigen::Vector3d x(rng.uniform(-8.0, 8.0), rng.uniform(-3.0, 3.0), rng.uniform(6.0, 30.0));
    scene.query_bearings.push_back(x.normalized());
    scene.train_bearings[i] = (scene.t_from_q * x).normalized();
    scene.query.keypoints.emplace_back(cv::Point2f(0, 0), 8.0f);
    scene.query.descriptors.row(i).copyTo(scene.train.descriptors.row(i));
    flip_bits(scene.train.descriptors.row(i), 8);
    // The copy: the same point seen 0.2 rad lower (far off its epipolar plane, which runs nearly horizontally).
    const Eigen::Vector3d b = scene.train_bearings[i];
    scene.train_bearings[points + i] = Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitX()) * b;
    scene.query.descriptors.row(i).copyTo(scene.train.descriptors.row(points + i));
    flip_bits(scene.train.descriptors.row(points + i), 6);
  }
  for (int i = 0; i < 2 * points; ++i) scene.train.keypoints.emplace_back(cv::Point2f(0, 0), 8.0f);
  return scene;
}

TEST(MatchAlongEpipolarPlanes, FindsMatchesTheGlobalRatioTestRefuses) {
  const EpipolarScene scene = MakeEpipolarScene(200, 5);
  WideBaselineOptions options;
  options.ratio = 0.85;  // the binary relocalization's (BinaryFeatureOptions)
  const std::vector<cv::DMatch> global = MatchWideBaseline(scene.query, scene.train, options);
  int global_right = 0;
  for (const cv::DMatch& m : global) global_right += m.trainIdx == m.queryIdx;
  EXPECT_LT(global_right, 20) << "the copies should hide most right matches from the global ratio test";

  const double band = 2.0 / 300.0;  // 2 px at a focal length of 300 px
  const std::vector<cv::DMatch> guided =
      MatchAlongEpipolarPlanes(scene.query, scene.train, scene.query_bearings, scene.train_bearings,
                               EssentialFromPose(scene.t_from_q), band, options);
  int right = 0;
  for (const cv::DMatch& m : guided) right += m.trainIdx == m.queryIdx;
  EXPECT_GE(right, 190);
  EXPECT_EQ(right, static_cast<int>(guided.size())) << "every guided match is a right one";

  // Along the planes of a wrong pose (the translation tilted 30 degrees upwards, about the optical axis) the right
  // matches are mostly not there.
  const Rigid3d wrong_pose(scene.t_from_q.rotation,
                           Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()) * scene.t_from_q.translation);
  const std::vector<cv::DMatch> wrong =
      MatchAlongEpipolarPlanes(scene.query, scene.train, scene.query_bearings, scene.train_bearings,
                               EssentialFromPose(wrong_pose), band, options);
  int wrong_right = 0;
  for (const cv::DMatch& m : wrong) wrong_right += m.trainIdx == m.queryIdx;
  EXPECT_LT(wrong_right, 20);
}

TEST(MatchAlongEpipolarPlanes, SkipsBearingsThatDoNotExist) {
  EpipolarScene scene = MakeEpipolarScene(50, 9);
  for (int i = 0; i < 10; ++i) scene.query_bearings[i].setZero();
  for (int i = 10; i < 20; ++i) scene.train_bearings[i].setZero();
  const std::vector<cv::DMatch> guided =
      MatchAlongEpipolarPlanes(scene.query, scene.train, scene.query_bearings, scene.train_bearings,
                               EssentialFromPose(scene.t_from_q), 2.0 / 300.0, WideBaselineOptions());
  for (const cv::DMatch& m : guided) {
    EXPECT_GE(m.queryIdx, 10);
    EXPECT_FALSE(m.trainIdx >= 10 && m.trainIdx < 20);
  }
  EXPECT_GE(guided.size(), 25u);
}

TEST(WideBaseline, BlankImageGivesNoFeaturesAndNoMatches) {
  const cv::Mat blank(240, 320, CV_8UC1, cv::Scalar(90));
  const auto features = ExtractWideBaselineFeatures(blank);
  EXPECT_EQ(features.size(), 0u);
  EXPECT_TRUE(MatchWideBaseline(features, features).empty());
}

}  // namespace
}  // namespace retrace
