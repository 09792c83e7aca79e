#include "retrace/geometry/essential.h"

#include <random>

#include <gtest/gtest.h>

#include "retrace/camera/perspective_camera.h"
#include "retrace/geometry/relative_pose.h"
#include "retrace/geometry/synthetic.h"
#include "retrace/geometry/triangulation.h"

namespace retrace {
namespace {

Rigid3d TestPose() {
  const Matrix3d r = Eigen::AngleAxisd(0.2, Vector3d(0.1, 1.0, -0.2).normalized()).toRotationMatrix();
  return Rigid3d(r, Vector3d(0.3, -0.1, -1.0).normalized());
}

TEST(Essential, EpipolarConstraintAndSampsonOnExactData) {
  const Rigid3d b_from_a = TestPose();
  const Matrix3d e = EssentialFromPose(b_from_a);
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  for (int i = 0; i < 50; ++i) {
    const Vector3d x_a(u(rng), u(rng), 10.0 + u(rng));
    const Vector3d fa = x_a.normalized();
    const Vector3d fb = (b_from_a * x_a).normalized();
    EXPECT_NEAR(fb.dot(e * fa), 0.0, 1e-12);
    EXPECT_NEAR(SampsonErrorSquared(e, fa, fb), 0.0, 1e-20);
  }
}

TEST(Essential, SampsonApproximatesAngularOffset) {
  // Perturb f_B by a small angle δ perpendicular to its epipolar plane: the Sampson error (both images together)
  // is δ |g_B| / sqrt(|g_A|² + |g_B|²): at most δ, and about δ / sqrt(2) when both images see the point alike.
  const Rigid3d b_from_a = TestPose();
  const Matrix3d e = EssentialFromPose(b_from_a);
  const Vector3d x_a(1.0, 0.5, 8.0);
  const Vector3d fa = x_a.normalized();
  const Vector3d fb = (b_from_a * x_a).normalized();
  const Vector3d normal = (e * fa).normalized();  // normal of the epipolar plane in B
  const double delta = 1e-3;
  const Vector3d fb_perturbed = (fb + delta * (normal - normal.dot(fb) * fb).normalized()).normalized();
  const double sampson = std::sqrt(SampsonErrorSquared(e, fa, fb_perturbed));
  EXPECT_LT(sampson, delta * 1.01);
  EXPECT_GT(sampson, delta / 2.0);
}

TEST(Essential, DecompositionContainsTruth) {
  const Rigid3d truth = TestPose();
  Rigid3d poses[4];
  ASSERT_TRUE(DecomposeEssential(-3.0 * EssentialFromPose(truth), poses));
  int matches = 0;
  for (const Rigid3d& pose : poses) {
    matches += RotationErrorDeg(pose.rotation, truth.rotation) < 1e-6 &&
               (pose.translation - truth.translation).norm() < 1e-6;
  }
  EXPECT_EQ(matches, 1);
  EXPECT_FALSE(DecomposeEssential(Matrix3d::Zero(), poses));
}

TEST(Essential, FivePointSolverFollowsRetraceConvention) {
  // Checks the convention of the solver (f_Bᵀ E f_A = 0): noise-free data, the true b_from_a must be a candidate.
  const PerspectiveCamera camera(640, 480, 500.0, 500.0, 319.5, 239.5);
  SyntheticTwoViewOptions options;
  options.noise_px = 0.0;
  options.outlier_ratio = 0.0;
  options.num_points = 5;
  const SyntheticTwoView scene = GenerateTwoView(camera, TestPose(), options);
  ASSERT_EQ(scene.bearings_a.size(), 5u);
  std::vector<Rigid3d> poses;
  SolveFivePoint(scene.bearings_a, scene.bearings_b, {0, 1, 2, 3, 4}, &poses);
  ASSERT_FALSE(poses.empty());
  double best = 1e9;
  for (const Rigid3d& pose : poses) {
    best = std::min(best, RotationErrorDeg(pose.rotation, scene.b_from_a.rotation) +
                              AngleBetweenDeg(pose.translation, scene.b_from_a.translation));
  }
  EXPECT_LT(best, 1e-6);
}

TEST(Triangulation, RecoversPointAndDepthsAndCheirality) {
  const Rigid3d b_from_a = TestPose();
  const Vector3d x_a(0.7, -0.4, 6.0);
  const Vector3d x_b = b_from_a * x_a;
  TriangulatedPoint point;
  ASSERT_TRUE(TriangulateMidpoint(b_from_a, x_a.normalized(), x_b.normalized(), &point));
  EXPECT_LT((point.point_in_a - x_a).norm(), 1e-9);
  EXPECT_NEAR(point.depth_a, x_a.norm(), 1e-9);
  EXPECT_NEAR(point.depth_b, x_b.norm(), 1e-9);
  EXPECT_TRUE(InFrontOfBothCameras(b_from_a, x_a.normalized(), x_b.normalized()));
  // The point mirrored behind both cameras (negated rays) is not in front.
  EXPECT_FALSE(InFrontOfBothCameras(b_from_a, -x_a.normalized(), -x_b.normalized()));
  // Parallel rays without a baseline: no triangulation, no crash.
  EXPECT_FALSE(TriangulateMidpoint(Rigid3d(), x_a.normalized(), x_a.normalized(), &point));
}

TEST(Triangulation, TangentResidualIsPixelOffsetNearTheAxis) {
  const double f = 500.0;
  // A point 1 px to the right of the bearing (0,0,1) at the image centre.
  const Vector2d r = TangentResidualPx(Vector3d(0, 0, 1), Vector3d(1.0 / f, 0.0, 1.0), f);
  EXPECT_NEAR(r.x(), 1.0, 1e-5);
  EXPECT_NEAR(r.y(), 0.0, 1e-9);
  const Vector2d down = TangentResidualPx(Vector3d(0, 0, 1), Vector3d(0.0, 2.0 / f, 1.0), f);
  EXPECT_NEAR(down.y(), 2.0, 1e-4);
  // A point behind the bearing is never a small residual.
  EXPECT_GT(TangentResidualPx(Vector3d(0, 0, 1), Vector3d(0.01, 0.0, -1.0), f).norm(), f);
}

}  // namespace
}  // namespace retrace
