#include "retrace/geometry/motion_uncertainty.h"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

#include "retrace/camera/perspective_camera.h"
#include "retrace/geometry/relative_pose.h"
#include "retrace/geometry/synthetic.h"

namespace retrace {
namespace {

// 320x240 with 80 degrees of horizontal field of view, as the simulator's camera.
const PerspectiveCamera kCamera(320, 240, 190.7, 190.7, 159.5, 119.5);

double Median(std::vector<double> values) {
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

struct MonteCarlo {
  double median_sigma_px = 0;             // estimated noise
  double median_direction_sigma_deg = 0;  // predicted
  double within_bound = 0;  // fraction of draws whose direction error lies within the predicted 95 % bound
  double median_ratio = 0;  // median of direction error / predicted σ
  int far_off = 0;          // draws whose direction is 10 degrees or more off
  int far_off_flagged = 0;  // ... and whose linear bound exceeds 10 degrees
  int far_off_in_region = 0;  // ... and whose likelihood-ratio region reaches 10 degrees (TestDirectionAt)
  int truth_in_region = 0;    // draws whose likelihood-ratio region reaches the true direction's angle
  int region_reaches_10 = 0;  // draws whose likelihood-ratio region reaches 10 degrees
};

// Draws 200 noisy scenes of `num_points` points (no outliers), estimates each motion as the Sampson optimum over all
// correspondences (the least-squares estimate the covariance describes), and compares its direction error with the
// uncertainty predicted from that draw alone.
MonteCarlo RunMonteCarlo(const Rigid3d& truth, int num_points, double min_distance, double max_distance,
                         double noise_px) {
  const PerspectiveCamera& camera = kCamera;
  constexpr int kDraws = 200;
  std::vector<double> sigma_px, direction_sigma, ratio;
  MonteCarlo result;
  int within = 0;
  for (int draw = 0; draw < kDraws; ++draw) {
    SyntheticTwoViewOptions options;
    options.num_points = num_points;
    options.noise_px = noise_px;
    options.outlier_ratio = 0.0;
    options.min_distance = min_distance;
    options.max_distance = max_distance;
    options.seed = 100 + draw;
    const SyntheticTwoView scene = GenerateTwoView(camera, truth, options);
    std::vector<int> all(scene.bearings_a.size());
    for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
    const Rigid3d start(truth.rotation, truth.translation.normalized());
    const Rigid3d estimate = internal::RefineOnSampson(scene.bearings_a, scene.bearings_b, all, start,
                                                       internal::GeneralPoseManifold(), 50);
    const MotionUncertainty uncertainty =
        EstimateMotionUncertainty(scene.bearings_a, scene.bearings_b, std::vector<bool>(all.size(), true), estimate,
                                  camera.FocalLength());
    const double error = AngleBetweenDeg(estimate.translation, truth.translation);
    sigma_px.push_back(uncertainty.sigma_px);
    direction_sigma.push_back(uncertainty.direction_sigma_deg);
    ratio.push_back(error / uncertainty.direction_sigma_deg);
    within += error <= uncertainty.direction_bound_deg;
    const std::vector<bool> mask(all.size(), true);
    const bool reaches_10 =
        TestDirectionAt(scene.bearings_a, scene.bearings_b, mask, estimate, camera.FocalLength(), 10.0).within_region;
    result.region_reaches_10 += reaches_10;
    result.truth_in_region +=
        TestDirectionAt(scene.bearings_a, scene.bearings_b, mask, estimate, camera.FocalLength(), error).within_region;
    if (error >= 10.0) {
      ++result.far_off;
      result.far_off_flagged += uncertainty.direction_bound_deg > 10.0;
      result.far_off_in_region += reaches_10;
    }
  }
  result.median_sigma_px = Median(sigma_px);
  result.median_direction_sigma_deg = Median(direction_sigma);
  result.within_bound = static_cast<double>(within) / kDraws;
  result.median_ratio = Median(ratio);
  std::cout << num_points << " points at " << min_distance << "-" << max_distance << " baselines, " << noise_px
            << " px: noise estimated " << result.median_sigma_px << " px, direction σ "
            << result.median_direction_sigma_deg << " deg (medians); " << 100 * result.within_bound
            << " % of the errors within the 95 % bound, median error / σ " << result.median_ratio << "; "
            << result.far_off << " draws 10 deg or more off, " << result.far_off_flagged << " of them beyond the "
            << "linear bound, " << result.far_off_in_region << " with the likelihood-ratio region reaching 10 deg; "
            << "that region reaches the true direction in " << result.truth_in_region << " of " << kDraws
            << " draws, 10 deg in " << result.region_reaches_10 << "\n";
  return result;
}

// The estimated noise: the pixel noise seen as an angle on the sphere, times the focal length. Towards the edge of
// this 80 degree field of view a pixel spans less angle (cos² 40° = 0.59 of the centre's, radially), so the estimate
// lies between 0.59 times the pixel noise and the pixel noise, less what the fit absorbs.
void ExpectNoiseRecovered(const MonteCarlo& run, double noise_px) {
  EXPECT_GE(run.median_sigma_px, 0.59 * noise_px);
  EXPECT_LE(run.median_sigma_px, 1.05 * noise_px);
}

const Rigid3d kForward(Eigen::AngleAxisd(2.0 * M_PI / 180.0, Vector3d::UnitY()).toRotationMatrix(),
                       Vector3d(0.05, 0.0, -1.0));

// Where the linearisation holds, the prediction matches the spread of the estimates: about 95 % of the direction
// errors lie within the 95 % bound (the largest σ is conservative for an elongated ellipse, the noise estimate a
// little low: at least 88 %), and the errors are of the order of σ, not far below (the bound would then reject good
// geometry). The likelihood-ratio region covers the true direction as often, and reaches 10 degrees rarely (20
// points: in a few draws whose points happen to be weak), never with 150.
TEST(MotionUncertainty, PredictsTheSpreadOfTheDirection) {
  const MonteCarlo strong = RunMonteCarlo(kForward, 150, 3.0, 15.0, 0.5);
  const MonteCarlo few = RunMonteCarlo(kForward, 20, 3.0, 15.0, 0.5);
  for (const MonteCarlo& run : {strong, few}) {
    ExpectNoiseRecovered(run, 0.5);
    EXPECT_GE(run.within_bound, 0.88);
    EXPECT_GE(run.median_ratio, 0.5);
    EXPECT_LE(run.median_ratio, 1.5);
    EXPECT_GE(run.truth_in_region, 0.9 * 200);
  }
  EXPECT_LT(strong.median_direction_sigma_deg, 1.0);
  EXPECT_GT(few.median_direction_sigma_deg, 2.0 * strong.median_direction_sigma_deg);
  EXPECT_EQ(strong.region_reaches_10, 0);
  EXPECT_LE(few.region_reaches_10, 0.1 * 200);
}

// Few points far away (a short baseline): beyond the linearisation, σ comes out too small (see the header) and the
// linear bound misses a third of the draws 10 degrees or more off; the likelihood-ratio region still covers the true
// direction, so it flags them.
TEST(MotionUncertainty, FlagsTheFarOffDirectionsOfAWeakPair) {
  const MonteCarlo weak = RunMonteCarlo(kForward, 20, 15.0, 60.0, 0.5);
  ExpectNoiseRecovered(weak, 0.5);
  EXPECT_GT(weak.median_ratio, 1.5) << "the premise: the linearised spread is underestimated here";
  EXPECT_LT(weak.far_off_flagged, 0.8 * weak.far_off) << "the premise: the linear bound misses far-off draws";
  ASSERT_GE(weak.far_off, 40);
  EXPECT_GE(weak.far_off_in_region, 0.9 * weak.far_off);
  EXPECT_GE(weak.truth_in_region, 0.9 * 200);
}

// `num_points` points 4-30 baselines ahead, 0.5 px noise, no outliers.
SyntheticTwoView ForwardScene(int num_points) {
  SyntheticTwoViewOptions options;
  options.num_points = num_points;
  options.outlier_ratio = 0.0;
  return GenerateTwoView(kCamera, kForward, options);
}

TEST(MotionUncertainty, TooFewPointsAreUndetermined) {
  const PerspectiveCamera& camera = kCamera;
  const SyntheticTwoView scene = ForwardScene(5);
  const MotionUncertainty uncertainty = EstimateMotionUncertainty(
      scene.bearings_a, scene.bearings_b, std::vector<bool>(5, true), kForward, camera.FocalLength());
  EXPECT_EQ(uncertainty.direction_sigma_deg, std::numeric_limits<double>::infinity());
  EXPECT_EQ(uncertainty.rotation_sigma_deg, std::numeric_limits<double>::infinity());
  EXPECT_TRUE(TestDirectionAt(scene.bearings_a, scene.bearings_b, std::vector<bool>(5, true), kForward,
                              camera.FocalLength(), 10.0)
                  .within_region);
}

// The region's bound is the F quantile: with many points, χ²₂(0.95) = 5.99.
TEST(MotionUncertainty, RegionBoundIsTheFQuantile) {
  const PerspectiveCamera& camera = kCamera;
  const SyntheticTwoView scene = ForwardScene(2000);
  const DirectionTest test = TestDirectionAt(scene.bearings_a, scene.bearings_b,
                                             std::vector<bool>(scene.bearings_a.size(), true), kForward,
                                             camera.FocalLength(), 10.0);
  EXPECT_NEAR(test.bound, 5.99, 0.03);
  EXPECT_FALSE(test.within_region);
  // On the circle 10 degrees around the estimate (refined from the truth: within a fraction of a degree of it).
  EXPECT_NEAR(AngleBetweenDeg(test.direction, kForward.translation), 10.0, 0.5);
}

}  // namespace
}  // namespace retrace
