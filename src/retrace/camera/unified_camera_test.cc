#include "retrace/camera/unified_camera.h"

#include <random>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/ccalib/omnidir.hpp>

namespace retrace {
namespace {

// A catadioptric-like camera (xi near 1) and a fisheye-like one (xi > 1), with realistic distortion.
UnifiedCamera CatadioptricCamera() {
  LensDistortion d;
  d.k1 = -0.12;
  d.k2 = 0.03;
  d.p1 = 0.0008;
  d.p2 = -0.0005;
  return UnifiedCamera(1280, 1024, 0.95, 760.0, 755.0, 641.3, 512.7, 0.4, d);
}

UnifiedCamera FisheyeCamera() {
  LensDistortion d;
  d.k1 = -0.05;
  d.k2 = 0.01;
  d.p1 = -0.0004;
  d.p2 = 0.0003;
  return UnifiedCamera(752, 480, 1.6, 720.0, 718.0, 376.1, 239.4, 0.0, d);
}

// Unproject every pixel (2 px grid) of the image that has a ray and reproject it.
void ExpectRoundTripOverImage(const UnifiedCamera& camera, double min_fraction_with_ray) {
  int total = 0, with_ray = 0;
  double max_error = 0.0;
  for (double y = 0; y <= camera.height() - 1; y += 2.0) {
    for (double x = 0; x <= camera.width() - 1; x += 2.0) {
      ++total;
      const Vector2d pixel(x, y);
      Vector3d bearing;
      if (!camera.Unproject(pixel, &bearing)) continue;
      ++with_ray;
      ASSERT_NEAR(bearing.norm(), 1.0, 1e-12);
      Vector2d reprojected;
      ASSERT_TRUE(camera.Project(2.5 * bearing, &reprojected)) << pixel.transpose();
      max_error = std::max(max_error, (reprojected - pixel).norm());
    }
  }
  EXPECT_LT(max_error, 1e-6);
  EXPECT_GE(with_ray, min_fraction_with_ray * total);
}

TEST(UnifiedCamera, RoundTripOverTheWholeImage) {
  ExpectRoundTripOverImage(CatadioptricCamera(), 1.0);
  ExpectRoundTripOverImage(FisheyeCamera(), 0.99);
}

TEST(UnifiedCamera, BearingRoundTripIncludingRaysBehind) {
  // xi = 0.95 sees more than a hemisphere: directions down to z_s = -0.95.
  const UnifiedCamera camera = CatadioptricCamera();
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0.0, 1.0);
  int behind = 0;
  for (int i = 0; i < 5000; ++i) {
    const Vector3d direction = Vector3d(n(rng), n(rng), n(rng)).normalized();
    Vector2d pixel;
    if (!camera.Project(direction, &pixel)) {
      EXPECT_LE(direction.z(), -0.95 + 1e-6);
      continue;
    }
    // The distortion polynomial is only invertible over a limited radius: test directions imaged near the image.
    if (!camera.InImage(pixel, -200.0)) continue;
    if (direction.z() < 0) ++behind;
    Vector3d bearing;
    ASSERT_TRUE(camera.Unproject(pixel, &bearing));
    EXPECT_LT((bearing - direction).norm(), 1e-9);
  }
  EXPECT_GT(behind, 100);
}

TEST(UnifiedCamera, ZeroXiIsThePinholeModel) {
  const UnifiedCamera unified(640, 480, 0.0, 500.0, 502.0, 320.0, 240.0);
  Vector2d pixel;
  ASSERT_TRUE(unified.Project(Vector3d(0.3, -0.2, 2.0), &pixel));
  EXPECT_NEAR(pixel.x(), 320.0 + 500.0 * 0.15, 1e-9);
  EXPECT_NEAR(pixel.y(), 240.0 - 502.0 * 0.1, 1e-9);
  EXPECT_FALSE(unified.Project(Vector3d(0.3, -0.2, -2.0), &pixel));
  EXPECT_NEAR(unified.FocalLength(), 501.0, 1e-12);
}

TEST(UnifiedCamera, AgreesWithOpenCvOmnidir) {
  const UnifiedCamera cameras[] = {CatadioptricCamera(), FisheyeCamera()};
  for (const UnifiedCamera& camera : cameras) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::vector<cv::Vec3d> points;
    std::vector<Vector2d> ours;
    while (points.size() < 500) {
      const Vector3d point(3.0 * u(rng), 3.0 * u(rng), 2.0 * u(rng) + 1.0);
      Vector2d pixel;
      if (!camera.Project(point, &pixel)) continue;
      points.emplace_back(point.x(), point.y(), point.z());
      ours.push_back(pixel);
    }
    cv::Matx33d k(camera.fx(), camera.skew(), camera.cx(), 0, camera.fy(), camera.cy(), 0, 0, 1);
    const LensDistortion& d = camera.distortion();
    cv::Matx14d distortion(d.k1, d.k2, d.p1, d.p2);
    std::vector<cv::Vec2d> theirs;
    cv::omnidir::projectPoints(points, theirs, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), k, camera.xi(), distortion);
    ASSERT_EQ(theirs.size(), ours.size());
    for (size_t i = 0; i < ours.size(); ++i) {
      EXPECT_NEAR(ours[i].x(), theirs[i][0], 1e-8);
      EXPECT_NEAR(ours[i].y(), theirs[i][1], 1e-8);
    }
    // And our unprojection agrees with cv::omnidir::undistortPoints (normalized perspective coordinates).
    std::vector<cv::Vec2d> pixels;
    for (size_t i = 0; i < 50; ++i) pixels.emplace_back(ours[i].x(), ours[i].y());
    std::vector<cv::Vec2d> normalized;
    cv::omnidir::undistortPoints(pixels, normalized, k, distortion, cv::Matx<double, 1, 1>(camera.xi()),
                                 cv::Matx33d::eye());
    for (size_t i = 0; i < pixels.size(); ++i) {
      Vector3d bearing;
      ASSERT_TRUE(camera.Unproject(ours[i], &bearing));
      if (bearing.z() < 0.05) continue;  // undistortPoints returns the perspective projection of the ray
      EXPECT_NEAR(bearing.x() / bearing.z(), normalized[i][0], 1e-6);
      EXPECT_NEAR(bearing.y() / bearing.z(), normalized[i][1], 1e-6);
    }
  }
}

TEST(UnifiedCamera, ScaledAndCloneSeeTheSameRays) {
  const UnifiedCamera camera = CatadioptricCamera();
  const auto half = camera.Scaled(0.5);
  const auto copy = camera.Clone();
  EXPECT_EQ(half->width(), 640);
  EXPECT_EQ(half->height(), 512);
  EXPECT_EQ(copy->type(), CameraModelType::kUnified);
  EXPECT_NEAR(half->FocalLength(), 0.5 * camera.FocalLength(), 1e-12);
  const Vector3d point(0.4, -0.3, -0.2);  // slightly behind the camera: visible for xi = 0.95
  Vector2d full_pixel, half_pixel, copy_pixel;
  ASSERT_TRUE(camera.Project(point, &full_pixel));
  ASSERT_TRUE(half->Project(point, &half_pixel));
  ASSERT_TRUE(copy->Project(point, &copy_pixel));
  EXPECT_LT((half_pixel - ((full_pixel.array() + 0.5) * 0.5 - 0.5).matrix()).norm(), 1e-9);
  EXPECT_LT((copy_pixel - full_pixel).norm(), 1e-12);
}

TEST(UnifiedCamera, FocalLengthMatchesAngularResolutionAtTheCentre) {
  const UnifiedCamera camera = FisheyeCamera();
  // A 1 mrad step at the axis moves the pixel by FocalLength() / 1000 px (skew and distortion are second order).
  Vector2d a, b;
  ASSERT_TRUE(camera.Project(Vector3d(0, 0, 1), &a));
  ASSERT_TRUE(camera.Project(Vector3d(std::sin(1e-3), 0, std::cos(1e-3)), &b));
  EXPECT_NEAR((b - a).norm(), camera.fx() / (1.0 + camera.xi()) * 1e-3, 1e-5);
}

}  // namespace
}  // namespace retrace
