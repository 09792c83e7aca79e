#include "retrace/geometry/planar_pose.h"

#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "retrace/camera/equirectangular_camera.h"
#include "retrace/camera/perspective_camera.h"
#include "retrace/geometry/essential.h"
#include "retrace/geometry/synthetic.h"

namespace retrace {
namespace {

constexpr double kDeg = M_PI / 180.0;

TEST(PlanarPose, EssentialHasFourNonZeroEntries) {
  const Rigid3d pose = PlanarPose(0.3, -0.7);
  const Matrix3d e = EssentialFromPose(pose);
  EXPECT_NEAR(e(0, 0), 0.0, 1e-15);
  EXPECT_NEAR(e(0, 2), 0.0, 1e-15);
  EXPECT_NEAR(e(1, 1), 0.0, 1e-15);
  EXPECT_NEAR(e(2, 0), 0.0, 1e-15);
  EXPECT_NEAR(e(2, 2), 0.0, 1e-15);
  EXPECT_NEAR(e(0, 1), -std::cos(-0.7), 1e-15);
  EXPECT_NEAR(e(2, 1), std::sin(-0.7), 1e-15);
  EXPECT_NEAR(e(1, 0), std::cos(0.3 + 0.7), 1e-15);
  EXPECT_NEAR(e(1, 2), std::sin(0.3 + 0.7), 1e-15);
}

TEST(PlanarPose, LinearSolverExactOnThreePoints) {
  const PerspectiveCamera camera(640, 480, 500.0, 500.0, 319.5, 239.5);
  SyntheticTwoViewOptions options;
  options.noise_px = 0.0;
  options.outlier_ratio = 0.0;
  options.num_points = 3;
  const Rigid3d truth = PlanarPose(7.0 * kDeg, 15.0 * kDeg + M_PI);  // forward motion (t_z < 0), turning right
  const SyntheticTwoView scene = GenerateTwoView(camera, truth, options);
  std::vector<Rigid3d> poses;
  ASSERT_TRUE(SolvePlanarLinear(scene.bearings_a, scene.bearings_b, {0, 1, 2}, &poses));
  ASSERT_EQ(poses.size(), 1u);  // the rotation is unique, cheirality picks the sign of t
  EXPECT_LT(RotationErrorDeg(poses[0].rotation, truth.rotation), 1e-8);
  EXPECT_LT(AngleBetweenDeg(poses[0].translation, truth.translation), 1e-8);
}

// The best achievable planar estimate: the Sampson optimum over the TRUE inliers, started from the truth.
Rigid3d GoldStandard(const SyntheticTwoView& scene) {
  std::vector<int> inliers;
  for (size_t i = 0; i < scene.is_outlier.size(); ++i) {
    if (!scene.is_outlier[i]) inliers.push_back(static_cast<int>(i));
  }
  return internal::RefineOnSampson(scene.bearings_a, scene.bearings_b, inliers, scene.b_from_a,
                                   internal::PlanarPoseManifold(), 50);
}

// 100 correspondences (0.5 px noise, 30 % outliers, points 3-15 baselines away). With `against_optimum`, the errors
// are compared with those of the optimum over the true inliers instead of fixed bounds.
void RunPlanarScene(const CameraModel& camera, const Rigid3d& truth, uint64_t seed, bool against_optimum = false) {
  SyntheticTwoViewOptions options;  // 100 points, 0.5 px noise, 30 % outliers
  options.min_distance = 3.0;
  options.max_distance = 15.0;
  options.seed = seed;
  const SyntheticTwoView scene = GenerateTwoView(camera, truth, options);
  ASSERT_EQ(scene.bearings_a.size(), 100u);
  const TwoViewGeometry g = EstimatePlanarRelativePose(scene.bearings_a, scene.bearings_b, camera.FocalLength());
  ASSERT_TRUE(g.success) << g.failure_message;
  const double rotation_error = RotationErrorDeg(g.b_from_a.rotation, truth.rotation);
  const double translation_error = AngleBetweenDeg(g.b_from_a.translation, truth.translation);
  const Rigid3d gold = GoldStandard(scene);
  const double gold_rotation = RotationErrorDeg(gold.rotation, truth.rotation);
  const double gold_translation = AngleBetweenDeg(gold.translation, truth.translation);
  std::printf("  seed %d: rotation %.3f deg (optimum %.3f), translation %.3f deg (optimum %.3f), %d inliers, "
              "sigma_p %.2f px\n", static_cast<int>(seed), rotation_error, gold_rotation, translation_error,
              gold_translation, g.num_inliers, g.sigma_p);
  if (against_optimum) {
    EXPECT_LT(rotation_error, 1.3 * gold_rotation + 0.05) << "seed " << seed;
    EXPECT_LT(translation_error, 1.5 * gold_translation + 1.0) << "seed " << seed;
  } else {
    EXPECT_LT(rotation_error, 0.1) << "seed " << seed;
    EXPECT_LT(translation_error, 1.0) << "seed " << seed;
  }
  // The result is planar by construction.
  EXPECT_NEAR(g.b_from_a.translation.y(), 0.0, 1e-12);
  EXPECT_NEAR(g.b_from_a.rotation(1, 1), 1.0, 1e-12);
  int rejected = 0, outliers = 0, kept = 0, inliers = 0;
  for (size_t i = 0; i < scene.is_outlier.size(); ++i) {
    if (scene.is_outlier[i]) {
      ++outliers;
      rejected += !g.inlier_mask[i];
    } else {
      ++inliers;
      kept += g.inlier_mask[i];
    }
    // Inliers are in front of both cameras.
    if (g.inlier_mask[i]) {
      EXPECT_TRUE(g.depths_a[i] > 0.0 && g.depths_b[i] > 0.0);
    }
  }
  EXPECT_GE(kept, 0.9 * inliers);
  EXPECT_GE(rejected, 0.8 * outliers);
}

TEST(PlanarPose, PerspectiveForwardMotionWithTurns) {
  const PerspectiveCamera camera(640, 480, 500.0, 500.0, 319.5, 239.5);
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    RunPlanarScene(camera, PlanarPose(-6.0 * kDeg, 170.0 * kDeg), seed);
    RunPlanarScene(camera, PlanarPose(10.0 * kDeg, 195.0 * kDeg), seed + 50);
  }
}

TEST(PlanarPose, PerspectiveSidewaysMotionReachesTheOptimum) {
  // Sideways translation with a yaw: nearly ambiguous for a 65° field of view (bas-relief ambiguity), even the
  // optimum over the true inliers has rotation errors up to ~0.16°.
  const PerspectiveCamera camera(640, 480, 500.0, 500.0, 319.5, 239.5);
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    RunPlanarScene(camera, PlanarPose(12.0 * kDeg, 100.0 * kDeg), seed + 50, /*against_optimum=*/true);
  }
}

TEST(PlanarPose, OmnidirectionalPlanarMotion) {
  const EquirectangularCamera camera(2400, 1200);  // 382 px per radian
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    RunPlanarScene(camera, PlanarPose(30.0 * kDeg, 60.0 * kDeg), seed);
    RunPlanarScene(camera, PlanarPose(-80.0 * kDeg, -120.0 * kDeg), seed + 50);
  }
}

TEST(PlanarPose, HeadingTowardsTheOtherCamera) {
  // B is 2 m ahead and 2 m to the right of A (A's frame): heading +45°, whatever B's orientation.
  for (double yaw : {0.0, 0.4, -1.2}) {
    const Rigid3d world_from_b(PlanarPose(yaw, 0.0).rotation, Vector3d(2.0, 0.0, 2.0));
    const Rigid3d b_from_a = world_from_b.Inverse();  // A is the world frame
    EXPECT_NEAR(PlanarHeading(b_from_a), 45.0 * kDeg, 1e-12);
  }
  // Straight behind, to the left.
  EXPECT_NEAR(std::abs(PlanarHeading(Rigid3d(Matrix3d::Identity(), Vector3d(0, 0, 1)))), M_PI, 1e-12);
  EXPECT_NEAR(PlanarHeading(Rigid3d(Matrix3d::Identity(), Vector3d(1, 0, 0))), -M_PI / 2.0, 1e-12);
}

TEST(PlanarPose, DegenerateInputFailsCleanly) {
  const double f = 500.0;
  EXPECT_FALSE(EstimatePlanarRelativePose({}, {}, f).success);
  const std::vector<Vector3d> a(2, Vector3d(0, 0, 1)), b(2, Vector3d(0, 0, 1));
  EXPECT_FALSE(EstimatePlanarRelativePose(a, b, f).success);
  const std::vector<Vector3d> same_a(40, Vector3d(0.1, 0.2, 1.0).normalized());
  const std::vector<Vector3d> same_b(40, Vector3d(0.12, 0.2, 1.0).normalized());
  const TwoViewGeometry g = EstimatePlanarRelativePose(same_a, same_b, f);
  EXPECT_FALSE(g.success);
  EXPECT_FALSE(std::isnan(g.sigma_p));
  // Pure rotation about the vertical axis.
  const PerspectiveCamera camera(640, 480, 500.0, 500.0, 319.5, 239.5);
  SyntheticTwoViewOptions options;
  options.outlier_ratio = 0.0;
  const Rigid3d rotation_only(PlanarPose(0.1, 0.0).rotation, Vector3d::Zero());
  const SyntheticTwoView scene = GenerateTwoView(camera, rotation_only, options);
  EXPECT_FALSE(EstimatePlanarRelativePose(scene.bearings_a, scene.bearings_b, f).success);
}

}  // namespace
}  // namespace retrace
