#include "retrace/repeat/taught_path.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "retrace/camera/perspective_camera.h"
#include "retrace/geometry/essential.h"
#include "retrace/repeat/linear_map_testing.h"

namespace retrace {
namespace {

// Carried scales of an arc whose true scale is `metres_per_unit`, with `window` arcs on each side: every node scale
// and every right fit off by the model's noise, the fits listed in `wrong` ((side, steps), factor) off by `factor`.
std::vector<CarriedScale> MakeChain(double metres_per_unit, int window,
                                    const std::vector<std::pair<std::pair<int, int>, double>>& wrong, unsigned seed) {
  std::mt19937 random(seed);
  std::normal_distribution<double> node_noise(0.0, 0.01), fit_noise(0.0, 0.02);
  std::vector<CarriedScale> chain;
  const auto fit = [&](int side, int steps, double carried_error) {
    double log_scale = std::log(metres_per_unit) + carried_error + fit_noise(random);
    for (const auto& [where, factor] : wrong) {
      if (where.first == side && where.second == steps) log_scale += std::log(factor);
    }
    chain.push_back({log_scale, side, steps, 0.002});
  };
  fit(0, 0, 0.0);
  for (const int side : {+1, -1}) {
    double carried_error = 0.0;  // the node scales' errors accumulate along the way
    for (int steps = 1; steps <= window; ++steps) {
      carried_error += node_noise(random);
      fit(side, steps, carried_error);
    }
  }
  return chain;
}

double MedianOfWindow(const std::vector<CarriedScale>& scales, int window) {
  std::vector<double> values;
  for (const CarriedScale& s : scales) {
    if (s.steps <= window) values.push_back(std::exp(s.log_metres_per_unit));
  }
  std::sort(values.begin(), values.end());
  return values[values.size() / 2];
}

TEST(CombineArcScalesTest, RecoversTheScaleThroughARunOfWrongGroundFits) {
  // The arc's own ground fit and the next two are wrong, all too large: the factors of a run measured on a
  // validation drive (seed108, arcs 54-56).
  const double truth = 2.0;
  const TaughtPathOptions options;
  for (unsigned seed = 1; seed <= 20; ++seed) {
    const std::vector<CarriedScale> chain =
        MakeChain(truth, options.scale_window, {{{0, 0}, 2.75}, {{1, 1}, 1.45}, {{1, 2}, 2.5}}, seed);
    // The median of the arcs within two of it, as before this model, is taken by the run of wrong fits.
    EXPECT_GT(std::abs(MedianOfWindow(chain, 2) / truth - 1), 0.3) << "seed " << seed;
    const CombinedScale combined = CombineArcScales(chain, options);
    ASSERT_TRUE(combined.valid);
    EXPECT_NEAR(combined.metres_per_unit / truth, 1.0, 0.04) << "seed " << seed;
    EXPECT_EQ(combined.inliers, 2 * options.scale_window + 1 - 3) << "seed " << seed;
    EXPECT_GT(combined.sigma, 0.005);
    EXPECT_LT(combined.sigma, options.ground_scale_sigma);
  }
}

TEST(CombineArcScalesTest, WeighsTheNearFitsMostWhenAllAreRight) {
  // Far arcs carry their scale through more node scales. With the fits ahead drifting away (0.4 % per step, all
  // within the right fits' spread) the estimate stays nearer the arc's own fit than the plain mean of the logs.
  const TaughtPathOptions options;
  std::vector<CarriedScale> scales{{0.0, 0, 0, 0.0}};
  double mean = 0.0;
  for (int steps = 1; steps <= options.scale_window; ++steps) {
    scales.push_back({0.004 * steps, +1, steps, 0.0});
    mean += scales.back().log_metres_per_unit / (options.scale_window + 1);
  }
  const CombinedScale combined = CombineArcScales(scales, options);
  ASSERT_TRUE(combined.valid);
  EXPECT_EQ(combined.inliers, options.scale_window + 1);
  EXPECT_GT(std::log(combined.metres_per_unit), 0.0);
  EXPECT_LT(std::log(combined.metres_per_unit), 0.5 * mean);
}

TEST(CombineArcScalesTest, OneFitIsTakenAsItIsAndNoneIsInvalid) {
  const TaughtPathOptions options;
  EXPECT_FALSE(CombineArcScales({}, options).valid);
  const CombinedScale one = CombineArcScales({{std::log(3.0), 0, 0, 0.05}}, options);
  ASSERT_TRUE(one.valid);
  EXPECT_NEAR(one.metres_per_unit, 3.0, 1e-9);
  // The fit's own σ (larger than ground_scale_sigma), over the responsibility of a lone fit (0.995).
  EXPECT_NEAR(one.sigma, 0.05, 1e-3);
}

TEST(TaughtPathOptionsTest, RejectsAScaleModelOutOfRange) {
  std::string error;
  TaughtPathOptions options;
  EXPECT_TRUE(options.Check(&error)) << error;
  options.relative_scale_sigma = 0.0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("relative_scale_sigma"), std::string::npos);
  options = TaughtPathOptions();
  options.ground_outlier_probability = 1.0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("ground_outlier_probability"), std::string::npos);
  options = TaughtPathOptions();
  options.ground_scale_sigma = -0.1;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("ground_scale_sigma"), std::string::npos);
}

// On a circle the tangents are the circle's, however unevenly the key-images are spaced (Catmull-Rom tangents, the
// directions from the previous to the next key-image, are not: 0.2 rad off at the second key-image here) and
// whatever yaw the camera is mounted with (only the headings' differences count).
TEST(KeyImageTangentsTest, FollowACircleWithUnevenKeyImagesAndAYawedCamera) {
  const double radius = 20.0;
  const std::vector<double> angles = {0.0, 0.1, 0.6, 0.75, 1.2};  // radians along a left turn
  const double mount_yaw = 5.0 * M_PI / 180;
  std::vector<Vector2d> centres, headings, truth;
  for (const double a : angles) {
    centres.emplace_back(-radius + radius * std::cos(a), radius * std::sin(a));  // (right, forward)
    truth.emplace_back(-std::sin(a), std::cos(a));
    headings.emplace_back(-std::sin(a + mount_yaw), std::cos(a + mount_yaw));
  }
  const std::vector<Vector2d> tangents = KeyImageTangents(centres, headings);
  ASSERT_EQ(tangents.size(), centres.size());
  for (size_t i = 0; i < tangents.size(); ++i) EXPECT_LT((tangents[i] - truth[i]).norm(), 1e-9) << i;
  const Vector2d catmull_rom = (centres[2] - centres[0]).normalized();
  EXPECT_GT((catmull_rom - truth[1]).norm(), 0.1);
}

TEST(KeyImageTangentsTest, AStraightRoadKeepsItsDirection) {
  const std::vector<Vector2d> centres = {{0, 0}, {0.3, 4}, {0.6, 8}, {0.9, 12}};
  const std::vector<Vector2d> headings(4, Vector2d(0.2, 1.0));  // a yawed camera, not along the road: no turn
  const Vector2d road = Vector2d(0.3, 4).normalized();
  for (const Vector2d& t : KeyImageTangents(centres, headings)) EXPECT_LT((t - road).norm(), 1e-12);
}

}  // namespace
}  // namespace retrace

namespace retrace {
namespace {

// heading_per_lateral is the regression of the heading error on the lateral offset through the pose's covariance.
// With a covariance of rank one, (δω, δC) = (u, v) ξ, the heading and the offset move together as the pose moves
// along (u, v), and the regression is the ratio of their changes — measured here by moving the pose and locating
// it again. A camera 0.4 m right of a straight 3 m arc, turned 0.05 rad, its ground 1.5 m below.
TEST(TaughtPathTest, HeadingPerLateralFollowsThePoseCovariance) {
  Map map = LinearMap(1);
  MapArc& arc = *map.MutableArc(0);
  arc.to_from_from = Rigid3d(Matrix3d::Identity(), Vector3d(0.0, 0.0, -1.0));  // b one unit ahead of a
  arc.ground_fit = MapArc::GroundFit{0.5, 0.005};                              // 3 m per unit
  TaughtPathOptions options;
  options.camera_height = 1.5;
  options.ground.normal_in_camera = Vector3d(0.0, 1.0, 0.0);
  const PerspectiveCamera camera(320, 240, 250.0, 250.0, 159.5, 119.5);
  TaughtPath path(map, camera, options);

  const auto pose_at = [](const Vector3d& centre, const Matrix3d& rotation) {
    return Rigid3d(rotation, -(rotation * centre));
  };
  const Vector3d centre(0.4 / 3.0, 0.0, 0.5);  // units
  const Matrix3d rotation = ExpSO3(Vector3d(0.0, -0.05, 0.0));
  for (const auto& [u, v] : {std::pair{Vector3d(0.0, 1.0, 0.0), Vector3d(-1.0, 0.0, 0.0)},
                             std::pair{Vector3d(0.1, 0.7, 0.2), Vector3d(0.5, 0.2, 0.3)},
                             std::pair{Vector3d(0.0, -0.3, 0.0), Vector3d(2.0, 0.0, 0.4)}}) {
    const PoseCovariance covariance{v * v.transpose(), u * u.transpose(), u * v.transpose()};
    const PathPose located = path.Locate(0, pose_at(centre, rotation), &covariance, 0);
    ASSERT_TRUE(located.valid);
    EXPECT_NEAR(located.lateral_m, 0.4, 1e-9);
    EXPECT_NEAR(located.heading_error_rad, 0.05, 1e-9);  // turned right of the path (about the downward normal)
    const double step = 1e-6;
    const PathPose moved = path.Locate(0, pose_at(centre + step * v, ExpSO3(step * u) * rotation), nullptr, 0);
    ASSERT_TRUE(moved.valid);
    const double expected =
        (moved.heading_error_rad - located.heading_error_rad) / (moved.lateral_m - located.lateral_m);
    EXPECT_NEAR(located.heading_per_lateral, expected, 1e-4 * std::max(1.0, std::abs(expected)));
  }
  // Without a covariance it is unknown.
  EXPECT_EQ(path.Locate(0, pose_at(centre, rotation), nullptr, 0).heading_per_lateral, 0.0);
}

}  // namespace
}  // namespace retrace
