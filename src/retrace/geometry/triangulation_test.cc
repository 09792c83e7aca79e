#include "retrace/geometry/triangulation.h"

#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

namespace retrace {
namespace {

constexpr double kFocalPx = 300.0;

// A camera at `centre` (world frame) that has turned by `yaw` radians about the vertical (y) axis.
Rigid3d CameraAt(const Vector3d& centre, double yaw) {
  Rigid3d cam_from_world;
  cam_from_world.rotation = Eigen::AngleAxisd(yaw, Vector3d::UnitY()).toRotationMatrix().transpose();
  cam_from_world.translation = -cam_from_world.rotation * centre;
  return cam_from_world;
}

Vector3d BearingOf(const Rigid3d& cam_from_world, const Vector3d& point) {
  return (cam_from_world.rotation * point + cam_from_world.translation).normalized();
}

// A bearing moved by an isotropic angular error of `sigma_px` pixels.
Vector3d Perturbed(const Vector3d& bearing, double sigma_px, std::mt19937* rng) {
  std::normal_distribution<double> noise(0.0, sigma_px / kFocalPx);
  Vector3d u, v;
  TangentBasis(bearing, &u, &v);
  return (bearing + noise(*rng) * u + noise(*rng) * v).normalized();
}

// Three key-images 3 units apart through a 24° turn (the shape of the drives where a camera beside the path lagged,
// docs/repeat.md), and a far point 23 baselines ahead, 3.4° from the first two's baseline (0.8 px of parallax).
struct TurnScene {
  std::vector<Rigid3d> cameras = {CameraAt(Vector3d(0, 0, 0), 0.0), CameraAt(Vector3d(0.3, 0, 3.0), 0.21),
                                  CameraAt(Vector3d(1.2, 0, 5.9), 0.42)};
  Vector3d point = Vector3d(10.0, -3.0, 70.0);
};

TEST(RefinePointMultiView, ConvergesToTheExactPointFromADepthThirtyPercentOff) {
  const TurnScene scene;
  std::vector<Vector3d> bearings;
  for (const Rigid3d& camera : scene.cameras) bearings.push_back(BearingOf(camera, scene.point));
  Vector3d refined;
  double worst = -1.0;
  ASSERT_TRUE(RefinePointMultiView(scene.cameras, bearings, 0.7 * scene.point, kFocalPx, &refined, &worst));
  EXPECT_LT((refined - scene.point).norm(), 1e-6 * scene.point.norm());
  EXPECT_LT(worst, 1e-6);
}

TEST(RefinePointMultiView, AThirdKeyImageInATurnFixesAFarPointsDepthBetterThanTwo) {
  // 0.1 px of noise on every bearing: the two-view midpoint of the first two key-images against the point refined
  // from all three, over the same draws. The third key-image, around the turn, doubles the baseline and sees the
  // point 9° from the second's.
  const TurnScene scene;
  std::mt19937 rng(7);
  const int trials = 400;
  double two_view_squared = 0.0, three_view_squared = 0.0;
  int refined_count = 0;
  const Rigid3d b_from_a = scene.cameras[1] * scene.cameras[0].Inverse();
  for (int trial = 0; trial < trials; ++trial) {
    std::vector<Vector3d> bearings;
    for (const Rigid3d& camera : scene.cameras) bearings.push_back(Perturbed(BearingOf(camera, scene.point), 0.1, &rng));
    TriangulatedPoint two_view;
    ASSERT_TRUE(TriangulateMidpoint(b_from_a, bearings[0], bearings[1], &two_view));
    const double true_depth = scene.point.norm();
    const double two_view_error = (two_view.point_in_a.norm() - true_depth) / true_depth;
    Vector3d refined;
    // Started where two views put it (the arc's point), as the localizer does.
    if (two_view.depth_a <= 0.0 ||
        !RefinePointMultiView(scene.cameras, bearings, two_view.point_in_a, kFocalPx, &refined)) {
      continue;
    }
    ++refined_count;
    two_view_squared += two_view_error * two_view_error;
    const double three_view_error = (refined.norm() - true_depth) / true_depth;
    three_view_squared += three_view_error * three_view_error;
  }
  ASSERT_GT(refined_count, trials * 9 / 10);
  const double two_view_rms = std::sqrt(two_view_squared / refined_count);
  const double three_view_rms = std::sqrt(three_view_squared / refined_count);
  // Measured: 0.188 against 0.052 (relative depth error, RMS; the two views' parallax is under a pixel).
  EXPECT_GT(two_view_rms, 0.1);
  EXPECT_LT(three_view_rms, 0.4 * two_view_rms);
}

TEST(RefinePointMultiView, RefusesTooFewViewsAndAPointBehindACamera) {
  const TurnScene scene;
  std::vector<Vector3d> bearings;
  for (const Rigid3d& camera : scene.cameras) bearings.push_back(BearingOf(camera, scene.point));
  Vector3d refined;
  EXPECT_FALSE(RefinePointMultiView({scene.cameras[0]}, {bearings[0]}, scene.point, kFocalPx, &refined));
  // Started behind the first camera: no point in front of every camera to descend from.
  EXPECT_FALSE(RefinePointMultiView(scene.cameras, bearings, -scene.point, kFocalPx, &refined));
}

}  // namespace
}  // namespace retrace
