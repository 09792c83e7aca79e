#include "retrace/geometry/point_transfer.h"

#include <algorithm>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>

#include "retrace/camera/perspective_camera.h"
#include "retrace/geometry/relative_pose.h"

namespace retrace {
namespace {

double Median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// World = camera A. Three cameras on a road: key-images A and B (2 m apart) and the current camera T between them,
// slightly off the path. Features: 3D points in front, observed with 0.5 px noise through a distorted camera.
class PointTransferTest : public ::testing::Test {
 protected:
  PointTransferTest()
      : camera_(752, 480, 460.0, 458.0, 370.0, 245.0, 0.0, LensDistortion{-0.28, 0.07, 0.0, 0.0002, 0.00002}) {
    const auto yaw = [](double deg) {
      return Eigen::AngleAxisd(deg * M_PI / 180.0, Vector3d::UnitY()).toRotationMatrix();
    };
    world_from_b_ = Rigid3d(yaw(6.0), Vector3d(0.3, 0.0, 2.0));
    world_from_t_ = Rigid3d(yaw(3.0), Vector3d(0.4, 0.05, 1.1));
    std::mt19937 rng(21);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    while (points_.size() < 150) {
      Vector3d ray;
      if (!camera_.Unproject(Vector2d(u(rng) * 751, u(rng) * 479), &ray)) continue;
      const Vector3d p = (5.0 + 25.0 * u(rng)) * ray;
      Vector2d pixel;
      if (!camera_.Project(world_from_b_.Inverse() * p, &pixel) || !camera_.InImage(pixel)) continue;
      if (!camera_.Project(world_from_t_.Inverse() * p, &pixel) || !camera_.InImage(pixel)) continue;
      points_.push_back(p);
    }
  }

  // Noisy bearings of the points in the camera at `world_from_cam`.
  std::vector<Vector3d> Observe(const Rigid3d& world_from_cam, uint64_t seed) const {
    std::mt19937 rng(seed);
    std::normal_distribution<double> noise(0.0, 0.5);
    std::vector<Vector3d> bearings;
    for (const Vector3d& p : points_) {
      Vector2d pixel;
      camera_.Project(world_from_cam.Inverse() * p, &pixel);
      Vector3d f;
      camera_.Unproject(pixel + Vector2d(noise(rng), noise(rng)), &f);
      bearings.push_back(f);
    }
    return bearings;
  }

  PerspectiveCamera camera_;
  Rigid3d world_from_b_, world_from_t_;
  std::vector<Vector3d> points_;  // in A's frame (= world)
};

TEST_F(PointTransferTest, MedianErrorBelowOnePixelWithEstimatedGeometries) {
  const std::vector<Vector3d> fa = Observe(Rigid3d(), 1), fb = Observe(world_from_b_, 2),
                              ft = Observe(world_from_t_, 3);
  // Teach: the arc geometry W (A, B). Repeat: the current geometry W_t:a from the features tracked now.
  const TwoViewGeometry arc = EstimateRelativePose(fa, fb, camera_.FocalLength());
  ASSERT_TRUE(arc.success) << arc.failure_message;
  // Half of the features are used for the current geometry and the scale; the other half is predicted (as features
  // that are not tracked now).
  std::vector<Vector3d> current_a, current_t;
  std::vector<int> shared_index;
  for (size_t i = 0; i < points_.size(); i += 2) {
    current_a.push_back(fa[i]);
    current_t.push_back(ft[i]);
    shared_index.push_back(static_cast<int>(i));
  }
  const TwoViewGeometry current = EstimateRelativePose(current_a, current_t, camera_.FocalLength());
  ASSERT_TRUE(current.success) << current.failure_message;
  std::vector<Vector3d> arc_shared, current_shared;
  for (size_t k = 0; k < shared_index.size(); ++k) {
    if (!current.inlier_mask[k] || !arc.inlier_mask[shared_index[k]]) continue;
    arc_shared.push_back(arc.points_in_a[shared_index[k]]);
    current_shared.push_back(current.points_in_a[k]);
  }
  const PointTransfer transfer =
      PointTransfer::Create(arc.b_from_a, current.b_from_a, ArcImage::kA, arc_shared, current_shared);
  ASSERT_TRUE(transfer.valid());
  // The arc has unit baseline |AB| = |(0.3, 0, 2)|: the current camera centre in arc units is T / |AB|.
  const double baseline = world_from_b_.translation.norm();
  const Vector3d centre_t = -transfer.current_from_a().rotation.transpose() * transfer.current_from_a().translation;
  EXPECT_LT((centre_t - world_from_t_.translation / baseline).norm(), 0.02);

  std::vector<double> errors, ratio_errors;
  for (size_t i = 1; i < points_.size(); i += 2) {  // features not used by the current geometry
    if (!arc.inlier_mask[i]) continue;
    const TransferredPoint predicted = transfer.Transfer(arc.points_in_a[i], camera_, ArcImage::kB);
    Vector2d truth;
    ASSERT_TRUE(camera_.Project(world_from_t_.Inverse() * points_[i], &truth));
    ASSERT_TRUE(predicted.projectable);
    errors.push_back((predicted.pixel - truth).norm());
    const double true_ratio = (world_from_t_.Inverse() * points_[i]).norm() /
                              (world_from_b_.Inverse() * points_[i]).norm();
    ratio_errors.push_back(std::abs(predicted.distance_ratio / true_ratio - 1.0));
  }
  ASSERT_GT(errors.size(), 50u);
  std::printf("  %zu transferred features: median error %.3f px, median distance-ratio error %.4f\n", errors.size(),
              Median(errors), Median(ratio_errors));
  EXPECT_LT(Median(errors), 1.0);
  EXPECT_LT(Median(ratio_errors), 0.02);
}

TEST_F(PointTransferTest, ExactWithNoiseFreeGeometriesAndCurrentGeometryToB) {
  // Ground-truth geometries with arbitrary units: the arc in unit baseline, the current geometry towards B in its
  // own unit (x 0.3). Transfer through B must reproduce the true pixels exactly.
  const Rigid3d a_from_world;  // A is the world
  const Rigid3d b_from_a = world_from_b_.Inverse();
  const double arc_unit = b_from_a.translation.norm();
  const Rigid3d arc(b_from_a.rotation, b_from_a.translation / arc_unit);
  const Rigid3d t_from_b = world_from_t_.Inverse() * world_from_b_;
  const double current_unit = 0.3 * t_from_b.translation.norm();
  const Rigid3d current(t_from_b.rotation, t_from_b.translation / current_unit);
  std::vector<Vector3d> arc_points, current_points;
  for (const Vector3d& p : points_) {
    arc_points.push_back(p / arc_unit);
    current_points.push_back((b_from_a * p) / current_unit);
  }
  const PointTransfer transfer = PointTransfer::Create(arc, current, ArcImage::kB, arc_points, current_points);
  ASSERT_TRUE(transfer.valid());
  EXPECT_NEAR(transfer.scale().scale, current_unit / arc_unit, 1e-12);
  for (size_t i = 0; i < points_.size(); ++i) {
    const TransferredPoint predicted = transfer.Transfer(arc_points[i], camera_, ArcImage::kA);
    Vector2d truth;
    camera_.Project(world_from_t_.Inverse() * points_[i], &truth);
    ASSERT_TRUE(predicted.in_image);
    EXPECT_LT((predicted.pixel - truth).norm(), 1e-6);
    EXPECT_NEAR(predicted.distance_ratio, (world_from_t_.Inverse() * points_[i]).norm() / points_[i].norm(), 1e-9);
  }
  // A point behind the current camera is not projectable.
  const TransferredPoint behind = transfer.Transfer(Vector3d(0.0, 0.0, -5.0), camera_);
  EXPECT_FALSE(behind.projectable);
  EXPECT_FALSE(behind.in_image);
}

TEST_F(PointTransferTest, InvalidWithoutSharedFeatures) {
  const PointTransfer transfer = PointTransfer::Create(Rigid3d(), Rigid3d(), ArcImage::kA, {}, {});
  EXPECT_FALSE(transfer.valid());
  EXPECT_FALSE(transfer.Transfer(Vector3d(0, 0, 5), camera_).projectable);
}

}  // namespace
}  // namespace retrace
