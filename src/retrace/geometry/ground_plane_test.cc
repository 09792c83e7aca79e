#include "retrace/geometry/ground_plane.h"

#include <cmath>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "retrace/camera/perspective_camera.h"

namespace retrace {
namespace {

// A textured ground y = height (world: x right, y down, z forward) seen by a 320x240 camera tilted down by `tilt`.
struct GroundScene {
  double height = 1.5;
  double tilt_deg = 5.0;
  PerspectiveCamera camera{320, 240, 250.0, 250.0, 160.0, 120.0};

  Matrix3d Tilt() const { return Eigen::AngleAxisd(-tilt_deg * M_PI / 180, Vector3d::UnitX()).toRotationMatrix(); }

  // Grey level of the ground at (x, z): smooth blobs of several sizes, like asphalt.
  static double Texture(double x, double z) {
    double v = 128 + 40 * std::sin(1.7 * x + 0.3 * z) * std::cos(1.1 * z - 0.4 * x) +
               30 * std::sin(4.3 * x - 2.9 * z + 1.0) + 20 * std::cos(7.1 * z + 5.3 * x);
    return std::clamp(v, 0.0, 255.0);
  }

  cv::Mat Render(const Rigid3d& world_from_cam) const {
    cv::Mat image(camera.height(), camera.width(), CV_8UC1, cv::Scalar(200));
    for (int y = 0; y < image.rows; ++y) {
      for (int x = 0; x < image.cols; ++x) {
        Vector3d ray;
        camera.Unproject(Vector2d(x, y), &ray);
        const Vector3d direction = world_from_cam.rotation * ray;
        if (direction.y() <= 1e-6) continue;  // sky
        const double t = (height - world_from_cam.translation.y()) / direction.y();
        const Vector3d hit = world_from_cam.translation + t * direction;
        image.at<uint8_t>(y, x) = static_cast<uint8_t>(Texture(hit.x(), hit.z()));
      }
    }
    return image;
  }
};

TEST(EstimateGroundPlane, RecoversTheHeightAndNormalOfATexturedRoad) {
  GroundScene scene;
  const Rigid3d world_from_a(scene.Tilt(), Vector3d::Zero());
  const Rigid3d world_from_b(scene.Tilt(), Vector3d(0.2, 0.0, 3.0));
  Rigid3d b_from_a = world_from_b.Inverse() * world_from_a;
  const double baseline = b_from_a.translation.norm();
  b_from_a.translation /= baseline;  // the arc's unit
  const cv::Mat a = scene.Render(world_from_a), b = scene.Render(world_from_b);

  const GroundPlane free = EstimateGroundPlane(a, b, scene.camera, b_from_a);
  ASSERT_TRUE(free.valid);
  const double expected = scene.height / baseline;
  const Vector3d expected_normal = scene.Tilt().transpose() * Vector3d::UnitY();
  EXPECT_NEAR(free.distance / expected, 1.0, 0.01);
  EXPECT_NEAR(free.distance_b / expected, 1.0, 0.01);
  EXPECT_LT(std::acos(std::min(1.0, free.normal.dot(expected_normal))) * 180 / M_PI, 0.5);
  EXPECT_GT(free.overlap, 0.9);

  // With the normal known, only d: the same answer.
  GroundPlaneOptions options;
  options.normal_in_camera = expected_normal;
  const GroundPlane fixed = EstimateGroundPlane(a, b, scene.camera, b_from_a, options);
  ASSERT_TRUE(fixed.valid);
  EXPECT_NEAR(fixed.distance_b / expected, 1.0, 0.005);

  // The common normal of several planes is their median.
  EXPECT_LT(std::acos(std::min(1.0, CommonGroundNormal({free, fixed, free}, 3)->dot(expected_normal))), 0.01);
  EXPECT_FALSE(CommonGroundNormal({free, fixed}, 3).has_value());
}

TEST(EstimateGroundPlane, RefusesImagesWithoutGroundTexture) {
  GroundScene scene;
  const cv::Mat blank(240, 320, CV_8UC1, cv::Scalar(90));
  Rigid3d b_from_a;
  b_from_a.translation = Vector3d(0, 0, -1);
  const GroundPlane plane = EstimateGroundPlane(blank, blank, scene.camera, b_from_a);
  EXPECT_FALSE(plane.valid);  // nothing constrains d: no answer rather than the search's first guess
  EXPECT_FALSE(EstimateGroundPlane(cv::Mat(), blank, scene.camera, b_from_a).valid);
}

TEST(GroundPlaneOptions, RejectsARegionOutsideTheImage) {
  GroundPlaneOptions options;
  EXPECT_TRUE(options.Check());
  options.roi_bottom = 1.5;
  EXPECT_FALSE(options.Check());
}

}  // namespace
}  // namespace retrace
