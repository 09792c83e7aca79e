#include "retrace/geometry/relative_pose.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "retrace/camera/equirectangular_camera.h"
#include "retrace/camera/perspective_camera.h"
#include "retrace/geometry/synthetic.h"

namespace retrace {
namespace {

Rigid3d MakePose(double angle_deg, const Vector3d& axis, const Vector3d& translation) {
  return Rigid3d(Eigen::AngleAxisd(angle_deg * M_PI / 180.0, axis.normalized()).toRotationMatrix(),
                 translation);
}

struct Errors {
  double rotation_deg;
  double translation_deg;
};

Errors PoseErrors(const Rigid3d& estimate, const Rigid3d& truth) {
  return {RotationErrorDeg(estimate.rotation, truth.rotation),
          AngleBetweenDeg(estimate.translation, truth.translation)};
}

Errors PoseErrors(const TwoViewGeometry& g, const Rigid3d& truth) { return PoseErrors(g.b_from_a, truth); }

// Fraction of true outliers flagged as outliers, and of true inliers kept.
void CheckInlierClassification(const TwoViewGeometry& g, const SyntheticTwoView& scene) {
  int outliers = 0, rejected = 0, inliers = 0, kept = 0;
  for (size_t i = 0; i < scene.is_outlier.size(); ++i) {
    if (scene.is_outlier[i]) {
      ++outliers;
      rejected += !g.inlier_mask[i];
    } else {
      ++inliers;
      kept += g.inlier_mask[i];
    }
  }
  EXPECT_GE(kept, 0.9 * inliers);
  // A random correspondence can fall near its epipolar line by chance; most are rejected.
  EXPECT_GE(rejected, 0.8 * outliers);
}

const Rigid3d kPerspectivePoses[] = {
    MakePose(5.0, Vector3d(0.1, 1.0, 0.05), Vector3d(0.2, 0.05, -1.0)),   // forward motion with a turn
    MakePose(3.0, Vector3d(1.0, 0.2, 0.1), Vector3d(-0.5, 0.3, -0.8)),    // general motion
    MakePose(10.0, Vector3d(0.0, 1.0, 0.0), Vector3d(1.0, 0.0, -0.3)),    // sideways + yaw: bas-relief ambiguity
};

// The best achievable estimate: the Sampson-error optimum over the TRUE inliers, started from the truth.
Rigid3d GoldStandard(const SyntheticTwoView& scene) {
  std::vector<int> inliers;
  for (size_t i = 0; i < scene.is_outlier.size(); ++i) {
    if (!scene.is_outlier[i]) inliers.push_back(static_cast<int>(i));
  }
  const Rigid3d truth(scene.b_from_a.rotation, scene.b_from_a.translation.normalized());
  return internal::RefineOnSampson(scene.bearings_a, scene.bearings_b, inliers, truth,
                                   internal::GeneralPoseManifold(), 50);
}

// Runs 5 seeds of 100 correspondences (0.5 px noise, 30 % outliers, points 3-15 baselines away) and checks the pose
// errors of every run, the inlier classification, σ_p and the triangulation.
void RunScenes(const CameraModel& camera, const Rigid3d& pose, uint64_t seed_base, double max_rotation_deg,
               double max_translation_deg) {
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    SyntheticTwoViewOptions options;  // 100 points, 0.5 px noise, 30 % outliers
    options.min_distance = 3.0;
    options.max_distance = 15.0;
    options.seed = seed_base + seed;
    const SyntheticTwoView scene = GenerateTwoView(camera, pose, options);
    ASSERT_EQ(scene.bearings_a.size(), 100u);
    const TwoViewGeometry g = EstimateRelativePose(scene.bearings_a, scene.bearings_b, camera.FocalLength());
    ASSERT_TRUE(g.success) << g.failure_message;
    const Errors errors = PoseErrors(g, scene.b_from_a);  // translation compared as a direction
    const Errors gold = PoseErrors(GoldStandard(scene), scene.b_from_a);
    std::printf("  seed %d: rotation %.3f deg (optimum %.3f), translation %.3f deg (optimum %.3f), sigma_p %.2f px\n",
                static_cast<int>(seed), errors.rotation_deg, gold.rotation_deg, errors.translation_deg,
                gold.translation_deg, g.sigma_p);
    EXPECT_LT(errors.rotation_deg, max_rotation_deg) << "seed " << seed;
    EXPECT_LT(errors.translation_deg, max_translation_deg) << "seed " << seed;
    EXPECT_NEAR(g.b_from_a.translation.norm(), 1.0, 1e-12);
    CheckInlierClassification(g, scene);
    // σ_p bounds the per-component reprojection noise in image B (midpoint residuals carry about half of the
    // 0.5 px noise of the two images) and exceeds the RMS of the same residuals.
    EXPECT_GT(g.sigma_p, 0.15);
    EXPECT_LT(g.sigma_p, 1.0);
    EXPECT_GT(g.sigma_p, g.rms_residual_px);
    // Triangulated inliers are close to the truth (scaled to a unit baseline) and in front of both cameras.
    const double scale = 1.0 / scene.b_from_a.translation.norm();
    int good = 0, checked = 0;
    for (size_t i = 0; i < scene.is_outlier.size(); ++i) {
      if (!g.inlier_mask[i] || scene.is_outlier[i]) continue;
      ++checked;
      const Vector3d truth = scale * scene.points_in_a[i];
      good += (g.points_in_a[i] - truth).norm() < 0.1 * truth.norm();
      EXPECT_GT(g.depths_a[i], 0.0);
      EXPECT_GT(g.depths_b[i], 0.0);
    }
    EXPECT_GE(good, 0.8 * checked);
  }
}

TEST(RelativePose, PerspectiveForwardMotion) {
  const PerspectiveCamera camera(640, 480, 500.0, 500.0, 319.5, 239.5);
  RunScenes(camera, kPerspectivePoses[0], 10, 0.1, 1.0);
}

TEST(RelativePose, PerspectiveGeneralMotion) {
  const PerspectiveCamera camera(640, 480, 500.0, 500.0, 319.5, 239.5);
  RunScenes(camera, kPerspectivePoses[1], 20, 0.1, 1.0);
}

TEST(RelativePose, PerspectiveSidewaysMotionReachesTheOptimum) {
  // Sideways translation with a yaw is nearly ambiguous for a 65° field of view (bas-relief ambiguity): even the
  // optimum over the true inliers has rotation errors of 0.05-0.2°. Check that the estimator gets close to it.
  const PerspectiveCamera camera(640, 480, 500.0, 500.0, 319.5, 239.5);
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    SyntheticTwoViewOptions options;
    options.min_distance = 3.0;
    options.max_distance = 15.0;
    options.seed = 30 + seed;
    const SyntheticTwoView scene = GenerateTwoView(camera, kPerspectivePoses[2], options);
    const TwoViewGeometry g = EstimateRelativePose(scene.bearings_a, scene.bearings_b, camera.FocalLength());
    ASSERT_TRUE(g.success) << g.failure_message;
    const Errors errors = PoseErrors(g, scene.b_from_a);
    const Errors gold = PoseErrors(GoldStandard(scene), scene.b_from_a);
    std::printf("  seed %d: rotation %.3f deg (optimum %.3f), translation %.3f deg (optimum %.3f)\n",
                static_cast<int>(seed), errors.rotation_deg, gold.rotation_deg, errors.translation_deg,
                gold.translation_deg);
    EXPECT_LT(errors.rotation_deg, 1.3 * gold.rotation_deg + 0.05) << "seed " << seed;
    EXPECT_LT(errors.translation_deg, 1.5 * gold.translation_deg + 1.0) << "seed " << seed;
    CheckInlierClassification(g, scene);
  }
}

TEST(RelativePose, OmnidirectionalPointsAllAround) {
  // 3600 x 1800: 573 px per radian, about the angular resolution of the 500 px perspective camera above.
  const EquirectangularCamera camera(3600, 1800);
  const Rigid3d poses[] = {
      MakePose(20.0, Vector3d(0.0, 1.0, 0.0), Vector3d(0.0, 0.0, 1.0)),
      MakePose(8.0, Vector3d(0.3, 1.0, -0.2), Vector3d(0.7, 0.1, -0.7)),
      MakePose(45.0, Vector3d(0.0, 1.0, 0.1), Vector3d(-1.0, 0.05, 0.2)),
  };
  for (int k = 0; k < 3; ++k) {
    SyntheticTwoViewOptions options;
    const SyntheticTwoView scene = GenerateTwoView(camera, poses[k], options);
    int behind = 0;
    for (const Vector3d& f : scene.bearings_a) behind += f.z() < 0.0;
    EXPECT_GT(behind, 20);  // really all around, including behind the camera
    RunScenes(camera, poses[k], 100 * (k + 1), 0.1, 1.0);
  }
}

TEST(RelativePose, DeterministicForEqualSeeds) {
  const PerspectiveCamera camera(640, 480, 500.0, 500.0, 319.5, 239.5);
  const SyntheticTwoView scene = GenerateTwoView(camera, kPerspectivePoses[0], SyntheticTwoViewOptions());
  const TwoViewGeometry g1 = EstimateRelativePose(scene.bearings_a, scene.bearings_b, camera.FocalLength());
  const TwoViewGeometry g2 = EstimateRelativePose(scene.bearings_a, scene.bearings_b, camera.FocalLength());
  ASSERT_TRUE(g1.success);
  EXPECT_EQ(g1.b_from_a.rotation, g2.b_from_a.rotation);
  EXPECT_EQ(g1.inlier_mask, g2.inlier_mask);
}

TEST(RelativePose, DegenerateInputFailsCleanly) {
  const PerspectiveCamera camera(640, 480, 500.0, 500.0, 319.5, 239.5);
  const double f = camera.FocalLength();
  const SyntheticTwoView scene = GenerateTwoView(camera, kPerspectivePoses[0], SyntheticTwoViewOptions());
  const auto expect_clean_failure = [](const TwoViewGeometry& g, const char* what) {
    EXPECT_FALSE(g.success) << what;
    EXPECT_FALSE(g.failure_message.empty()) << what;
    EXPECT_TRUE(g.b_from_a.rotation.allFinite()) << what;
    EXPECT_TRUE(g.b_from_a.translation.allFinite()) << what;
    EXPECT_FALSE(std::isnan(g.sigma_p)) << what;
  };

  // Fewer than five points (and the empty input).
  std::vector<Vector3d> a4(scene.bearings_a.begin(), scene.bearings_a.begin() + 4);
  std::vector<Vector3d> b4(scene.bearings_b.begin(), scene.bearings_b.begin() + 4);
  TwoViewGeometry g = EstimateRelativePose(a4, b4, f);
  expect_clean_failure(g, "four points");
  EXPECT_EQ(g.failure, TwoViewFailure::kTooFewCorrespondences);
  expect_clean_failure(EstimateRelativePose({}, {}, f), "no points");

  // Sizes differ, non-unit bearings, bad focal length.
  std::vector<Vector3d> b_short(scene.bearings_b.begin(), scene.bearings_b.end() - 1);
  g = EstimateRelativePose(scene.bearings_a, b_short, f);
  expect_clean_failure(g, "sizes differ");
  EXPECT_EQ(g.failure, TwoViewFailure::kInvalidInput);
  std::vector<Vector3d> a_nan = scene.bearings_a;
  a_nan[3] = Vector3d(NAN, 0, 1);
  expect_clean_failure(EstimateRelativePose(a_nan, scene.bearings_b, f), "NaN bearing");
  expect_clean_failure(EstimateRelativePose(scene.bearings_a, scene.bearings_b, 0.0), "zero focal");

  // All-identical points.
  const std::vector<Vector3d> same_a(50, Vector3d(0.1, 0.2, 1.0).normalized());
  const std::vector<Vector3d> same_b(50, Vector3d(0.12, 0.19, 1.0).normalized());
  expect_clean_failure(EstimateRelativePose(same_a, same_b, f), "identical points");

  // Pure rotation (no baseline), with noise.
  SyntheticTwoViewOptions options;
  options.outlier_ratio = 0.0;
  const SyntheticTwoView rotation_only =
      GenerateTwoView(camera, MakePose(5.0, Vector3d(0.2, 1.0, 0.0), Vector3d::Zero()), options);
  g = EstimateRelativePose(rotation_only.bearings_a, rotation_only.bearings_b, f);
  expect_clean_failure(g, "pure rotation");

  // Invalid options.
  TwoViewOptions bad;
  bad.ransac.confidence = 1.5;
  g = EstimateRelativePose(scene.bearings_a, scene.bearings_b, f, bad);
  expect_clean_failure(g, "bad options");
  EXPECT_EQ(g.failure, TwoViewFailure::kInvalidOptions);
}

TEST(RelativePose, AGoodGuessNeedsFewSamplesAndABadOneDoesNoHarm) {
  // While tracking, the previous frame's geometry is the guess: scored first, it lets the adaptive loop stop after
  // RansacOptions::min_iterations_with_guess samples when it explains the correspondences (10 % outliers here).
  const PerspectiveCamera camera(640, 480, 500.0, 500.0, 319.5, 239.5);
  SyntheticTwoViewOptions scene_options;
  scene_options.outlier_ratio = 0.1;
  scene_options.min_distance = 3.0;
  scene_options.max_distance = 15.0;
  const Rigid3d truth = kPerspectivePoses[0];
  const SyntheticTwoView scene = GenerateTwoView(camera, truth, scene_options);
  TwoViewOptions options;
  options.ransac.min_iterations = 30;
  const double f = camera.FocalLength();
  const TwoViewGeometry unguided = EstimateRelativePose(scene.bearings_a, scene.bearings_b, f, options);
  // The previous frame's geometry: the truth moved by a small step.
  const Rigid3d previous = MakePose(5.3, Vector3d(0.1, 1.0, 0.05), Vector3d(0.21, 0.05, -0.97));
  const TwoViewGeometry guided = EstimateRelativePose(scene.bearings_a, scene.bearings_b, f, options, &previous);
  ASSERT_TRUE(unguided.success && guided.success) << unguided.failure_message << guided.failure_message;
  std::printf("  samples: %d unguided, %d with a good guess\n", unguided.num_iterations, guided.num_iterations);
  EXPECT_GE(unguided.num_iterations, 30);
  EXPECT_LE(guided.num_iterations, 10);
  EXPECT_LT(PoseErrors(guided, truth).rotation_deg, 0.1);
  EXPECT_LT(PoseErrors(guided, truth).translation_deg, 1.0);
  EXPECT_NEAR(guided.sigma_p, unguided.sigma_p, 0.05);
  // A wrong guess (the camera backwards and turned) explains nothing: the loop samples as usual.
  const Rigid3d wrong = MakePose(40.0, Vector3d(1.0, 0.0, 0.0), Vector3d(0.0, 1.0, 1.0));
  const TwoViewGeometry misled = EstimateRelativePose(scene.bearings_a, scene.bearings_b, f, options, &wrong);
  ASSERT_TRUE(misled.success) << misled.failure_message;
  EXPECT_GE(misled.num_iterations, options.ransac.min_iterations_with_guess);
  EXPECT_LT(PoseErrors(misled, truth).rotation_deg, 0.1);
  EXPECT_LT(PoseErrors(misled, truth).translation_deg, 1.0);
}

// The samples that find a model of at least k inliers among N correspondences with confidence p: an all-inlier
// sample of 5 has probability >= (k / N)^5, so log(1 - p) / log(1 - (k / N)^5) of them (relocalization screens its
// candidates with this count). Known answers, then 200 scenes of 50 correspondences with exactly 30 inliers: the
// count finds the model (nearly) as the formula says, and a quarter of it does not.
TEST(RelativePose, SamplesEnoughForAMinimumInlierCount) {
  EXPECT_EQ(internal::RequiredIterations(0.5, 5, 0.999), 218);
  EXPECT_EQ(internal::RequiredIterations(1.0, 5, 0.999), 0);
  EXPECT_EQ(internal::RequiredIterations(0.0, 5, 0.999), std::numeric_limits<int>::max());
  const PerspectiveCamera camera(320, 240, 250.0, 250.0, 159.5, 119.5);
  const int enough = internal::RequiredIterations(30.0 / 50.0, 5, 0.999);
  EXPECT_EQ(enough, 86);
  int found_enough = 0, found_quarter = 0, scenes = 0;
  for (uint64_t seed = 1; seed <= 200; ++seed) {
    SyntheticTwoViewOptions scene_options;
    scene_options.num_points = 50;
    scene_options.outlier_ratio = 0.4;
    scene_options.seed = seed;
    const SyntheticTwoView scene = GenerateTwoView(camera, kPerspectivePoses[seed % 3], scene_options);
    if (scene.bearings_a.size() != 50u) continue;
    ++scenes;
    for (const int samples : {enough, enough / 4}) {
      TwoViewOptions options;
      options.ransac.min_iterations = 1;
      options.ransac.max_iterations = samples;
      options.ransac.seed = seed;
      const TwoViewGeometry g = EstimateRelativePose(scene.bearings_a, scene.bearings_b, camera.FocalLength(), options);
      // Found: a model keeping 90 % of the 30 inliers (the 0.5 px noise puts one or two beyond the threshold; a
      // model from a sample with an outlier keeps far fewer).
      const bool found = g.success && g.num_inliers >= 27;
      (samples == enough ? found_enough : found_quarter) += found;
    }
  }
  std::printf("  %d scenes: the model found with %d samples in %d, with %d in %d\n", scenes, enough, found_enough,
              enough / 4, found_quarter);
  ASSERT_GE(scenes, 150);
  // The count is for exact samples (99.9 %); a sample of five noisy inliers sometimes gives a model that keeps too
  // few of the others (Chum et al. 2003, locally optimized RANSAC), hence a little less (98 % here).
  EXPECT_GE(found_enough, scenes * 95 / 100);
  EXPECT_LT(found_quarter, scenes * 90 / 100);  // 1 - (1 - 0.6^5)^21 = 82 %: the count matters
}

TEST(RelativePose, TheGuessDecidesBetweenTheTwoMotionsOfAPlanarScene) {
  // Features on one facade (a plane): the essential matrix then admits two motions that fit the correspondences
  // (almost) equally (the planar ambiguity); teach met it in turns, where a key-image's geometry jumped to the
  // mirrored motion for one frame. With the previous frame's geometry as the guess the right one is kept.
  const PerspectiveCamera camera(640, 480, 500.0, 500.0, 319.5, 239.5);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.3);
  // The camera turns 25 degrees to the left while it moves forward (camera frame: x right, y down, z forward);
  // the facade is the plane x = 6 m to its right, in front of it.
  const Rigid3d truth = MakePose(-25.0, Vector3d::UnitY(), Vector3d::Zero());
  const Vector3d centre_b(-1.2, 0.0, 3.0);
  const Rigid3d b_from_a(truth.rotation, -truth.rotation * centre_b);
  std::vector<Vector3d> bearings_a, bearings_b;
  while (bearings_a.size() < 120) {
    const Vector3d point(6.0, -3.0 + 6.0 * uniform(rng), 8.0 + 30.0 * uniform(rng));
    Vector2d pa, pb;
    if (!camera.Project(point, &pa) || !camera.Project(b_from_a * point, &pb)) continue;
    if (!camera.InImage(pa, 0.0) || !camera.InImage(pb, 0.0)) continue;
    Vector3d fa, fb;
    camera.Unproject(pa + Vector2d(noise(rng), noise(rng)), &fa);
    camera.Unproject(pb + Vector2d(noise(rng), noise(rng)), &fb);
    bearings_a.push_back(fa);
    bearings_b.push_back(fb);
  }
  const Rigid3d expected(b_from_a.rotation, b_from_a.translation.normalized());
  // The previous frame's geometry: the motion a little earlier on the same turn.
  const Rigid3d previous_a_to_b = MakePose(-23.0, Vector3d::UnitY(), Vector3d::Zero());
  const Vector3d previous_centre(-1.1, 0.0, 2.8);
  const Rigid3d previous(previous_a_to_b.rotation, -previous_a_to_b.rotation * previous_centre);
  TwoViewOptions options;
  options.ransac.min_iterations = 20;
  options.ransac.min_iterations_with_guess = 20;
  int mirrored_without_guess = 0;
  for (uint64_t seed = 1; seed <= 20; ++seed) {
    options.ransac.seed = seed;
    const TwoViewGeometry guided =
        EstimateRelativePose(bearings_a, bearings_b, camera.FocalLength(), options, &previous);
    ASSERT_TRUE(guided.success) << guided.failure_message;
    EXPECT_LT(PoseErrors(guided, expected).rotation_deg, 1.0) << "seed " << seed;
    EXPECT_LT(PoseErrors(guided, expected).translation_deg, 5.0) << "seed " << seed;
    const TwoViewGeometry unguided = EstimateRelativePose(bearings_a, bearings_b, camera.FocalLength(), options);
    mirrored_without_guess += unguided.success && PoseErrors(unguided, expected).rotation_deg > 5.0;
  }
  std::printf("  without the guess, %d of 20 seeds chose a motion more than 5 degrees off\n", mirrored_without_guess);
  EXPECT_GT(mirrored_without_guess, 0) << "the scene should be ambiguous";
}

// IsInlierOfPose applies the estimators' inlier test to one correspondence: it agrees with the masks that
// EvaluateTwoViewGeometry gives for the estimate and for the true pose with matches moved across their epipolar lines
// by twice the threshold, keeps true matches moved along their epipolar line and rejects them moved across it by ten
// times the threshold.
TEST(RelativePose, OneCorrespondenceIsTestedAsTheEstimatorTestsItsInliers) {
  const PerspectiveCamera camera(640, 480, 500.0, 500.0, 319.5, 239.5);
  SyntheticTwoViewOptions options;  // 100 points, 0.5 px noise, 30 % outliers
  const SyntheticTwoView scene = GenerateTwoView(camera, kPerspectivePoses[1], options);
  const double threshold_px = TwoViewOptions().ransac.max_error_px;
  const double focal = camera.FocalLength();
  const TwoViewGeometry g = EstimateRelativePose(scene.bearings_a, scene.bearings_b, focal);
  ASSERT_TRUE(g.success) << g.failure_message;
  const Rigid3d truth(scene.b_from_a.rotation, scene.b_from_a.translation.normalized());
  std::vector<Vector3d> inliers_a, along_b, across_b, far_b;
  for (size_t i = 0; i < scene.bearings_a.size(); ++i) {
    EXPECT_EQ(IsInlierOfPose(g.b_from_a, scene.bearings_a[i], scene.bearings_b[i], focal, threshold_px),
              g.inlier_mask[i])
        << i;
    if (scene.is_outlier[i]) continue;
    // The noiseless match in B, and the directions along and across its epipolar line there.
    Vector2d exact, farther;
    ASSERT_TRUE(camera.Project(truth * scene.points_in_a[i], &exact));
    ASSERT_TRUE(camera.Project(truth * (1.05 * scene.points_in_a[i]), &farther));
    const Vector2d along = (farther - exact).normalized();
    const Vector2d across(-along.y(), along.x());
    inliers_a.push_back(scene.bearings_a[i]);
    const std::array<std::pair<std::vector<Vector3d>*, Vector2d>, 3> shifts{{{&along_b, 0.5 * threshold_px * along},
                                                                             {&across_b, 2.0 * threshold_px * across},
                                                                             {&far_b, 10.0 * threshold_px * across}}};
    for (const auto& [moved, shift] : shifts) {
      moved->emplace_back();
      ASSERT_TRUE(camera.Unproject(exact + shift, &moved->back()));
    }
  }
  TwoViewGeometry across = g;
  across.b_from_a = truth;
  EvaluateTwoViewGeometry(inliers_a, across_b, focal, threshold_px, TwoViewOptions().sigma_p_probability, &across);
  int kept = 0, rejected_across = 0;
  for (size_t i = 0; i < inliers_a.size(); ++i) {
    kept += IsInlierOfPose(truth, inliers_a[i], along_b[i], focal, threshold_px);
    const bool inlier_across = IsInlierOfPose(truth, inliers_a[i], across_b[i], focal, threshold_px);
    EXPECT_EQ(inlier_across, across.inlier_mask[i]) << i;
    rejected_across += !inlier_across;
    EXPECT_FALSE(IsInlierOfPose(truth, inliers_a[i], far_b[i], focal, threshold_px)) << i;
  }
  EXPECT_GE(kept, 0.95 * inliers_a.size());
  EXPECT_GT(rejected_across, inliers_a.size() / 2);  // not a test that accepts everything moved by 2 thresholds
}

}  // namespace
}  // namespace retrace
