// Relative pose on real data: KITTI odometry sequence 07 (shared data), SIFT matches, against ground-truth poses.

#include <cstdio>
#include <memory>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "retrace/camera/camera_io.h"
#include "retrace/dataset/ground_truth.h"
#include "retrace/geometry/relative_pose.h"
#include "retrace/geometry/two_view_matching.h"
#include "retrace/util/testing.h"

namespace retrace {
namespace {

cv::Mat Frame(const std::filesystem::path& dir, int index) {
  char name[32];
  std::snprintf(name, sizeof(name), "image_0/%06d.png", index);
  return cv::imread((dir / name).string(), cv::IMREAD_GRAYSCALE);
}

struct KittiPair {
  int a, b;
};

class TwoViewKittiTest : public ::testing::TestWithParam<KittiPair> {};

TEST_P(TwoViewKittiTest, RelativePoseMatchesGroundTruth) {
  RETRACE_REQUIRE_SHARED_DATA(dir, "kitti07");
  const KittiPair pair = GetParam();
  const cv::Mat image_a = Frame(dir, pair.a), image_b = Frame(dir, pair.b);
  ASSERT_FALSE(image_a.empty());
  ASSERT_FALSE(image_b.empty());
  // KITTI's calib.txt has no image size: the size of the first image is passed.
  const std::unique_ptr<CameraModel> camera_model = ReadCameraFile(dir / "calib.txt", image_a.size());
  const CameraModel& camera = *camera_model;
  const std::vector<TimedPose> poses = ReadKittiPoses(dir / "poses.txt");
  ASSERT_GT(poses.size(), static_cast<size_t>(pair.b));
  // x_B = R x_A + t: b_from_a = world_from_b⁻¹ world_from_a.
  const Rigid3d truth = poses[pair.b].world_from_cam.Inverse() * poses[pair.a].world_from_cam;

  const PixelMatches matches = MatchTwoViewFeatures(image_a, image_b);
  std::vector<Vector3d> bearings_a, bearings_b;
  MatchesToBearings(matches, camera, camera, &bearings_a, &bearings_b);
  const TwoViewGeometry g = EstimateRelativePose(bearings_a, bearings_b, camera.FocalLength());
  ASSERT_TRUE(g.success) << g.failure_message;
  const double rotation_error = RotationErrorDeg(g.b_from_a.rotation, truth.rotation);
  const double translation_error = AngleBetweenDeg(g.b_from_a.translation, truth.translation);
  std::printf("  frames %d-%d: %zu matches, %d inliers, rotation error %.3f deg, translation error %.3f deg, "
              "sigma_p %.3f px, rms %.3f px\n",
              pair.a, pair.b, bearings_a.size(), g.num_inliers, rotation_error, translation_error, g.sigma_p,
              g.rms_residual_px);
  EXPECT_LT(rotation_error, 0.3);
  EXPECT_LT(translation_error, 3.0);
  EXPECT_GT(g.num_inliers, 100);
  EXPECT_LT(g.sigma_p, 1.0);

}

INSTANTIATE_TEST_SUITE_P(Kitti07, TwoViewKittiTest,
                         ::testing::Values(KittiPair{0, 5}, KittiPair{0, 10}, KittiPair{50, 60}),
                         [](const ::testing::TestParamInfo<KittiPair>& info) {
                           return "frames_" + std::to_string(info.param.a) + "_" + std::to_string(info.param.b);
                         });

}  // namespace
}  // namespace retrace
