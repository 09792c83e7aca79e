#include "retrace/nav/camera_mount.h"

#include <cmath>
#include <random>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

namespace retrace {
namespace {

using Eigen::AngleAxisd;
using Eigen::Matrix3d;
using Eigen::Vector3d;

// A camera mounted with `camera_from_level` on a robot driving on flat ground (the level frame: y down, z ahead).
class MountedCamera {
 public:
  explicit MountedCamera(const Matrix3d& camera_from_level) : mount_(camera_from_level) {}

  // The arc between two key-images: the robot moves by `position` (in the first's level frame, y = 0) and turns by
  // `yaw` about the vertical. x_to = R x_from + t in the camera frames, |t| = 1.
  MapArc Arc(const Vector3d& position, double yaw) const {
    const Matrix3d turn = AngleAxisd(yaw, Vector3d::UnitY()).toRotationMatrix();
    MapArc arc;
    arc.to_from_from.rotation = mount_ * turn.transpose() * mount_.transpose();
    arc.to_from_from.translation = (-mount_ * turn.transpose() * position).normalized();
    return arc;
  }

  Vector3d TrueDown() const { return mount_ * Vector3d::UnitY(); }

 private:
  Matrix3d mount_;
};

Matrix3d Mount(double pitch, double roll) {
  return (AngleAxisd(pitch, Vector3d::UnitX()) * AngleAxisd(roll, Vector3d::UnitZ())).toRotationMatrix();
}

double AngleBetween(const Vector3d& a, const Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0));
}

TEST(CameraMountTest, LevelFrameOfALevelCameraIsTheCameraFrame) {
  EXPECT_TRUE(LevelFromCamera(Vector3d::UnitY()).isApprox(Matrix3d::Identity(), 1e-12));
  const Matrix3d level = LevelFromCamera(Vector3d(0.1, 0.9, 0.2));
  EXPECT_TRUE((level * level.transpose()).isApprox(Matrix3d::Identity(), 1e-12));
  EXPECT_NEAR(level.determinant(), 1.0, 1e-12);
  EXPECT_TRUE((level * Vector3d(0.1, 0.9, 0.2).normalized()).isApprox(Vector3d::UnitY(), 1e-12));
}

TEST(CameraMountTest, MapWithoutArcsIsLevel) {
  const CameraMount estimate = EstimateCameraMount(Map());
  EXPECT_TRUE(estimate.level_from_camera.isApprox(Matrix3d::Identity()));
  EXPECT_EQ(estimate.translations + estimate.rotations, 0);
}

// A straight route constrains the pitch only; the no-roll prior fills in the rest.
TEST(CameraMountTest, StraightRouteGivesThePitch) {
  const double pitch = 5.0 * M_PI / 180;
  const MountedCamera camera(Mount(pitch, 0.0));
  std::mt19937 random(3);
  std::normal_distribution<double> noise(0.0, 0.01);
  Map map;
  for (int i = 0; i < 20; ++i) map.AddArc(camera.Arc(Vector3d(noise(random), 0, 5 + noise(random)), noise(random)));
  const CameraMount estimate = EstimateCameraMount(map);
  EXPECT_LT(AngleBetween(estimate.down, camera.TrueDown()), 0.2 * M_PI / 180);
  EXPECT_NEAR(estimate.tilt_rad(), pitch, 0.2 * M_PI / 180);
  EXPECT_EQ(estimate.rotations, 0);
  // In the level frame the motion is horizontal.
  const MapArc arc = camera.Arc(Vector3d(0, 0, 1), 0.0);
  const Vector3d centre = -arc.to_from_from.rotation.transpose() * arc.to_from_from.translation;
  EXPECT_NEAR((estimate.level_from_camera * centre).y(), 0.0, 0.005);
}

// Turns and sideways moves give the roll as well, and a wrong arc (a false link pointing anywhere) is dropped.
TEST(CameraMountTest, TurnsGivePitchAndRollAndAWrongArcIsDropped) {
  const MountedCamera camera(Mount(4.0 * M_PI / 180, -3.0 * M_PI / 180));
  std::mt19937 random(7);
  std::normal_distribution<double> noise(0.0, 0.005);
  Map map;
  for (int i = 0; i < 30; ++i) {
    const double yaw = (i % 5 == 4) ? 0.6 : noise(random);  // every fifth arc turns a corner
    map.AddArc(camera.Arc(Vector3d(i % 5 == 4 ? 2.0 : noise(random), 0, 4 + noise(random)), yaw));
  }
  MapArc wrong;
  wrong.to_from_from.rotation = AngleAxisd(0.8, Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  wrong.to_from_from.translation = Vector3d(0.3, -0.9, 0.3).normalized();
  map.AddArc(wrong);

  const CameraMount estimate = EstimateCameraMount(map);
  EXPECT_LT(AngleBetween(estimate.down, camera.TrueDown()), 0.2 * M_PI / 180);
  EXPECT_EQ(estimate.rotations, 6);
  EXPECT_GE(estimate.dropped, 2);  // the wrong arc's translation and rotation axis
  EXPECT_EQ(estimate.translations, 30);
}

}  // namespace
}  // namespace retrace
