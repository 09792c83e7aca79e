#include "retrace/geometry/absolute_pose.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "retrace/camera/equirectangular_camera.h"
#include "retrace/camera/perspective_camera.h"
#include "retrace/geometry/synthetic.h"

namespace retrace {
namespace {

Rigid3d MakePose(double angle_deg, const Vector3d& axis, const Vector3d& translation) {
  return Rigid3d(Eigen::AngleAxisd(angle_deg * M_PI / 180.0, axis.normalized()).toRotationMatrix(),
                 translation);
}

Vector3d Centre(const Rigid3d& cam_from_world) {
  return -cam_from_world.rotation.transpose() * cam_from_world.translation;
}

// A reconstruction (the scene's points in A's frame, each moved along its ray from A by Gaussian noise of
// `depth_noise` times its distance: triangulation fixes the direction from a key-image well and the depth
// less so) and the current camera B observing it.
struct Scene {
  SyntheticTwoView view;
  std::vector<Vector3d> points;
};

Scene MakeScene(const CameraModel& camera, const Rigid3d& b_from_a, double outlier_ratio, double depth_noise,
                uint64_t seed) {
  SyntheticTwoViewOptions options;  // 100 points, 0.5 px noise
  options.outlier_ratio = outlier_ratio;
  options.min_distance = 3.0;
  options.max_distance = 30.0;
  options.seed = seed;
  Scene scene;
  scene.view = GenerateTwoView(camera, b_from_a, options);
  std::mt19937_64 rng(seed + 1000);
  std::normal_distribution<double> noise(0.0, 1.0);
  for (const Vector3d& p : scene.view.points_in_a) {
    scene.points.push_back(p * (1.0 + depth_noise * noise(rng)));
  }
  return scene;
}

TEST(AbsolutePose, ExactWithoutNoise) {
  const PerspectiveCamera camera(640, 480, 500.0, 500.0, 319.5, 239.5);
  const Rigid3d truth = MakePose(7.0, Vector3d(0.1, 1.0, 0.0), Vector3d(0.3, -0.1, -2.0));
  SyntheticTwoViewOptions options;
  options.noise_px = 0.0;
  options.outlier_ratio = 0.0;
  const SyntheticTwoView view = GenerateTwoView(camera, truth, options);
  const AbsolutePose pose = EstimateAbsolutePose(view.points_in_a, view.bearings_b, camera.FocalLength());
  ASSERT_TRUE(pose.success) << pose.failure_message;
  EXPECT_EQ(pose.num_inliers, static_cast<int>(view.points_in_a.size()));
  EXPECT_LT((Centre(pose.cam_from_world) - Centre(truth)).norm(), 1e-6);
  EXPECT_LT((pose.cam_from_world.rotation - truth.rotation).norm(), 1e-6);
  EXPECT_LT(pose.sigma_p, 1e-4);
}

// 100 correspondences, 0.5 px noise, 30 % outliers, map points off by 2 % of their depth: the camera centre
// is recovered to a small fraction of the distance between the two cameras (the arc length, in repeat), the
// outliers are rejected and σ_p bounds the residuals.
void CheckNoisyScenes(const CameraModel& camera, const Rigid3d& truth, double max_centre_error) {
  const double baseline = truth.translation.norm();
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    const Scene scene = MakeScene(camera, truth, 0.3, 0.02, seed);
    const AbsolutePose pose = EstimateAbsolutePose(scene.points, scene.view.bearings_b, camera.FocalLength());
    ASSERT_TRUE(pose.success) << pose.failure_message;
    const double centre_error = (Centre(pose.cam_from_world) - Centre(truth)).norm() / baseline;
    int kept = 0, inliers = 0, rejected = 0, outliers = 0;
    for (size_t i = 0; i < scene.view.is_outlier.size(); ++i) {
      if (scene.view.is_outlier[i]) {
        ++outliers;
        rejected += !pose.inlier_mask[i];
      } else {
        ++inliers;
        kept += pose.inlier_mask[i];
      }
    }
    std::printf(
        "  seed %d: centre error %.4f baselines, %d/%d inliers kept, %d/%d outliers rejected, sigma_p %.2f "
        "px\n",
        static_cast<int>(seed), centre_error, kept, inliers, rejected, outliers, pose.sigma_p);
    EXPECT_LT(centre_error, max_centre_error) << "seed " << seed;
    EXPECT_GE(kept, 0.8 * inliers);
    EXPECT_GE(rejected, 0.9 * outliers);
    EXPECT_GT(pose.sigma_p, pose.rms_residual_px);
    EXPECT_LT(pose.sigma_p, 2.0);
  }
}

TEST(AbsolutePose, PerspectiveForwardMotionWithOutliers) {
  const PerspectiveCamera camera(640, 480, 500.0, 500.0, 319.5, 239.5);
  CheckNoisyScenes(camera, MakePose(5.0, Vector3d(0.1, 1.0, 0.05), Vector3d(0.2, 0.05, -2.0)), 0.02);
}

TEST(AbsolutePose, PanoramaSeesAllAround) {
  const EquirectangularCamera camera(1024, 512);
  CheckNoisyScenes(camera, MakePose(20.0, Vector3d(0.0, 1.0, 0.0), Vector3d(1.0, 0.0, -1.5)), 0.03);
}

TEST(AbsolutePose, DeterministicForASeed) {
  const PerspectiveCamera camera(640, 480, 500.0, 500.0, 319.5, 239.5);
  const Scene scene = MakeScene(camera, MakePose(3.0, Vector3d(0, 1, 0), Vector3d(0, 0, -1.0)), 0.3, 0.01, 9);
  const AbsolutePose first = EstimateAbsolutePose(scene.points, scene.view.bearings_b, camera.FocalLength());
  const AbsolutePose second = EstimateAbsolutePose(scene.points, scene.view.bearings_b, camera.FocalLength());
  ASSERT_TRUE(first.success);
  EXPECT_EQ(first.inlier_mask, second.inlier_mask);
  EXPECT_EQ(first.cam_from_world.translation, second.cam_from_world.translation);
}

TEST(AbsolutePose, FailuresAreReported) {
  const PerspectiveCamera camera(640, 480, 500.0, 500.0, 319.5, 239.5);
  const Scene scene = MakeScene(camera, MakePose(3.0, Vector3d(0, 1, 0), Vector3d(0, 0, -1.0)), 0.0, 0.0, 3);
  // Too few correspondences.
  const std::vector<Vector3d> few_points(scene.points.begin(), scene.points.begin() + 4);
  const std::vector<Vector3d> few_bearings(scene.view.bearings_b.begin(), scene.view.bearings_b.begin() + 4);
  AbsolutePose pose = EstimateAbsolutePose(few_points, few_bearings, camera.FocalLength());
  EXPECT_FALSE(pose.success);
  EXPECT_NE(pose.failure_message.find("too few"), std::string::npos) << pose.failure_message;
  // Sizes differ, bearings not unit, focal length not positive, points not finite.
  EXPECT_FALSE(EstimateAbsolutePose(scene.points, few_bearings, camera.FocalLength()).success);
  std::vector<Vector3d> bad_bearings = scene.view.bearings_b;
  bad_bearings[0] *= 2.0;
  EXPECT_FALSE(EstimateAbsolutePose(scene.points, bad_bearings, camera.FocalLength()).success);
  EXPECT_FALSE(EstimateAbsolutePose(scene.points, scene.view.bearings_b, 0.0).success);
  std::vector<Vector3d> bad_points = scene.points;
  bad_points[3].x() = std::nan("");
  EXPECT_FALSE(EstimateAbsolutePose(bad_points, scene.view.bearings_b, camera.FocalLength()).success);
  // All outliers: no pose supported by enough points.
  std::vector<Vector3d> shuffled = scene.points;
  std::rotate(shuffled.begin(), shuffled.begin() + 37, shuffled.end());
  pose = EstimateAbsolutePose(shuffled, scene.view.bearings_b, camera.FocalLength());
  EXPECT_FALSE(pose.success && pose.num_inliers > 10) << pose.num_inliers;
}

}  // namespace
}  // namespace retrace

namespace retrace {
namespace {

// The centre covariance predicts the spread of the estimated camera centre: over many noisy scenes (0.5 px noise,
// exact points, no outliers) the squared Mahalanobis distance of the estimate from the truth averages 3 (χ² with
// 3 degrees of freedom), and the covariance is neither far too small nor far too large.
TEST(AbsolutePose, CentreCovarianceMatchesTheSpread) {
  const PerspectiveCamera camera(640, 480, 500.0, 500.0, 319.5, 239.5);
  const Rigid3d truth = MakePose(5.0, Vector3d(0.0, 1.0, 0.0), Vector3d(0.2, 0.0, -1.5));
  double sum_mahalanobis = 0.0;
  int trials = 0;
  for (uint64_t seed = 1; seed <= 200; ++seed) {
    SyntheticTwoViewOptions options;
    options.outlier_ratio = 0.0;
    options.min_distance = 3.0;
    options.max_distance = 30.0;
    options.seed = seed;
    const SyntheticTwoView view = GenerateTwoView(camera, truth, options);
    const AbsolutePose pose = EstimateAbsolutePose(view.points_in_a, view.bearings_b, camera.FocalLength());
    ASSERT_TRUE(pose.success) << pose.failure_message;
    ASSERT_TRUE(pose.covariance_valid);
    const Vector3d error = Centre(pose.cam_from_world) - Centre(truth);
    sum_mahalanobis += error.dot(pose.centre_covariance.inverse() * error);
    ++trials;
  }
  const double mean = sum_mahalanobis / trials;
  EXPECT_GT(mean, 3.0 * 0.7);
  EXPECT_LT(mean, 3.0 * 1.4);
}

}  // namespace
}  // namespace retrace
