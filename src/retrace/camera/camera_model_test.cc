#include <random>

#include <gtest/gtest.h>

#include "retrace/camera/equirectangular_camera.h"
#include "retrace/camera/perspective_camera.h"

namespace retrace {
namespace {

// EuRoC cam0 (radial-tangential) and the OpenCV chessboard camera: real, strong distortions.
PerspectiveCamera EurocCamera() {
  LensDistortion d;
  d.k1 = -0.28340811;
  d.k2 = 0.07395907;
  d.p1 = 0.00019359;
  d.p2 = 1.76187114e-05;
  return PerspectiveCamera(752, 480, 458.654, 457.296, 367.215, 248.375, 0.0, d);
}

PerspectiveCamera ChessboardCamera() {
  LensDistortion d;
  d.k1 = -0.26637;
  d.k2 = -0.03859;
  d.k3 = 0.23839;
  d.p1 = 0.00178;
  d.p2 = -0.00028;
  return PerspectiveCamera(640, 480, 535.9157, 535.9157, 342.2832, 235.5708, 0.0, d);
}

// Max over a dense grid covering the whole image of |distort(undistort(p)) - p| in pixels.
double MaxRoundTripErrorPx(const PerspectiveCamera& camera) {
  double max_error = 0.0;
  for (double y = 0; y <= camera.height() - 1; y += 2.0) {
    for (double x = 0; x <= camera.width() - 1; x += 2.0) {
      const Vector2d p(x, y);
      max_error = std::max(max_error, (camera.DistortPixel(camera.UndistortPixel(p)) - p).norm());
    }
  }
  return max_error;
}

TEST(PerspectiveCamera, DistortionRoundTripBelowOneHundredthPixel) {
  EXPECT_LT(MaxRoundTripErrorPx(EurocCamera()), 0.01);
  EXPECT_LT(MaxRoundTripErrorPx(ChessboardCamera()), 0.01);
}

TEST(PerspectiveCamera, ProjectUnprojectAgree) {
  const PerspectiveCamera camera = EurocCamera();
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int i = 0; i < 1000; ++i) {
    const Vector2d pixel(u(rng) * 751, u(rng) * 479);
    Vector3d bearing;
    ASSERT_TRUE(camera.Unproject(pixel, &bearing));
    EXPECT_NEAR(bearing.norm(), 1.0, 1e-12);
    Vector2d reprojected;
    ASSERT_TRUE(camera.Project(3.7 * bearing, &reprojected));
    EXPECT_LT((reprojected - pixel).norm(), 1e-6);
  }
  Vector2d pixel;
  EXPECT_FALSE(camera.Project(Vector3d(0.1, 0.2, -1.0), &pixel));
}

TEST(PerspectiveCamera, PinholeProjectsKnownPoint) {
  const PerspectiveCamera camera(1226, 370, 707.0912, 707.0912, 601.8873, 183.1104);
  Vector2d pixel;
  ASSERT_TRUE(camera.Project(Vector3d(1.0, -0.5, 10.0), &pixel));
  EXPECT_NEAR(pixel.x(), 601.8873 + 70.70912, 1e-9);
  EXPECT_NEAR(pixel.y(), 183.1104 - 35.35456, 1e-9);
}

TEST(PerspectiveCamera, ScaledCameraSeesTheSameRays) {
  const PerspectiveCamera camera = ChessboardCamera();
  const auto half = camera.Scaled(0.5);
  EXPECT_EQ(half->width(), 320);
  EXPECT_EQ(half->height(), 240);
  const Vector3d point(0.4, -0.3, 2.0);
  Vector2d full_pixel, half_pixel;
  ASSERT_TRUE(camera.Project(point, &full_pixel));
  ASSERT_TRUE(half->Project(point, &half_pixel));
  EXPECT_LT((half_pixel - ((full_pixel.array() + 0.5) * 0.5 - 0.5).matrix()).norm(), 1e-9);
}

TEST(EquirectangularCamera, RoundTripAndAxes) {
  const EquirectangularCamera camera(1024, 512);
  Vector2d pixel;
  ASSERT_TRUE(camera.Project(Vector3d(0, 0, 1), &pixel));  // forward = image centre
  EXPECT_NEAR(pixel.x(), 511.5, 1e-9);
  EXPECT_NEAR(pixel.y(), 255.5, 1e-9);
  ASSERT_TRUE(camera.Project(Vector3d(1, 0, 0), &pixel));  // right = three quarters across
  EXPECT_NEAR(pixel.x(), 767.5, 1e-9);
  ASSERT_TRUE(camera.Project(Vector3d(0, 0, -1), &pixel));  // behind is visible too
  std::mt19937 rng(2);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int i = 0; i < 1000; ++i) {
    const Vector3d direction = Vector3d(n(rng), n(rng), n(rng)).normalized();
    ASSERT_TRUE(camera.Project(5.0 * direction, &pixel));
    Vector3d bearing;
    ASSERT_TRUE(camera.Unproject(pixel, &bearing));
    EXPECT_LT((bearing - direction).norm(), 1e-9);
  }
}

}  // namespace
}  // namespace retrace
