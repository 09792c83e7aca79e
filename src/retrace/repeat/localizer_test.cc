// Unit tests of the repeat decisions on synthetic geometry: transition criterion (Segvic 2009 eq. (9)), prudence
// rules (eqs. (7), (8)) and σ_p gating.

#include "retrace/repeat/localizer.h"

#include <cmath>

#include <gtest/gtest.h>

#include "retrace/util/error.h"

namespace retrace {
namespace {

Matrix3d Yaw(double degrees) {
  const double r = degrees * M_PI / 180.0;
  Matrix3d m;
  m << std::cos(r), 0, std::sin(r), 0, 1, 0, -std::sin(r), 0, std::cos(r);
  return m;
}

// Camera with centre `centre` (world = frame of key-image a) and world_from_cam rotation `rotation`.
Rigid3d CamFromWorld(const Vector3d& centre, const Matrix3d& rotation = Matrix3d::Identity()) {
  return Rigid3d(rotation.transpose(), -rotation.transpose() * centre);
}

// The arc a -> b: b is 1 unit ahead of a and slightly to the right, turned by 10 degrees.
struct SyntheticArc {
  Vector3d centre_b = Vector3d(0.2, 0.0, 1.0).normalized();
  Matrix3d rotation_b = Yaw(10);
  Rigid3d b_from_a = CamFromWorld(centre_b, rotation_b);
};

TwoViewGeometry Geometry(const Rigid3d& pose, double sigma_p, bool success = true) {
  TwoViewGeometry g;
  g.success = success;
  g.b_from_a = pose;
  g.sigma_p = sigma_p;
  return g;
}

TEST(LocateOnArc, ProjectsTheCameraCentreOnTheArc) {
  const SyntheticArc arc;
  const Vector3d centre = 0.3 * arc.centre_b + Vector3d(0.05, 0.0, 0.0);
  const ArcPosition p = LocateOnArc(CamFromWorld(centre, Yaw(-25)), arc.b_from_a);
  ASSERT_TRUE(p.valid);
  EXPECT_NEAR(p.along, centre.dot(arc.centre_b), 1e-12);
  EXPECT_NEAR(p.distance_to_from, centre.norm(), 1e-12);
  EXPECT_NEAR(p.distance_to_to, (centre - arc.centre_b).norm(), 1e-12);
}

TEST(DecideTransition, FiresExactlyWhenTheCameraCrossesThePlaneThroughB) {
  // Segvic 2009, eq. (9): the plane through b's centre perpendicular to the direction of travel a -> b, whatever the
  // lateral offset and heading of the camera.
  const SyntheticArc arc;
  const Vector3d travel = arc.centre_b;
  const Vector3d lateral = travel.cross(Vector3d::UnitY()).normalized();
  const double margin = 0.1;
  for (const double lateral_offset : {-0.3, 0.0, 0.4}) {
    for (const double yaw : {-30.0, 0.0, 15.0}) {
      const auto decide = [&](double along) {
        const Vector3d centre = along * travel + lateral_offset * lateral;
        return DecideTransition(LocateOnArc(CamFromWorld(centre, Yaw(yaw)), arc.b_from_a), margin);
      };
      EXPECT_EQ(decide(0.97), 0) << lateral_offset << " " << yaw;
      EXPECT_EQ(decide(1.03), +1) << lateral_offset << " " << yaw;
      EXPECT_EQ(decide(0.5), 0) << lateral_offset << " " << yaw;
      // Backward (reversing past a) only beyond the margin behind a.
      EXPECT_EQ(decide(-0.05), 0) << lateral_offset << " " << yaw;
      EXPECT_EQ(decide(-0.2), -1) << lateral_offset << " " << yaw;
    }
  }
  // No position (no estimate passed the σ_p gate): no transition.
  EXPECT_EQ(DecideTransition(ArcPosition(), margin), 0);
}

TEST(DecideResumption, FollowsEquationsSevenAndEight) {
  const SyntheticArc arc;
  const auto policy_at = [&](double along) {
    return DecideResumption(LocateOnArc(CamFromWorld(along * arc.centre_b), arc.b_from_a));
  };
  // Start of the arc: the previous arc's features may come back (distance to a < 0.3), not the next arc's.
  EXPECT_TRUE(policy_at(0.1).previous);
  EXPECT_FALSE(policy_at(0.1).next);
  // Middle: neither.
  EXPECT_FALSE(policy_at(0.45).previous);
  EXPECT_FALSE(policy_at(0.45).next);
  // Boundaries: 0.29 / 0.31 from a, 0.49 / 0.51 from b.
  EXPECT_TRUE(policy_at(0.29).previous);
  EXPECT_FALSE(policy_at(0.31).previous);
  EXPECT_FALSE(policy_at(0.49).next);
  EXPECT_TRUE(policy_at(0.51).next);
  // Near b: the next arc's features.
  EXPECT_TRUE(policy_at(0.9).next);
  EXPECT_FALSE(policy_at(0.9).previous);
  // No position, no resumption of neighbours.
  EXPECT_FALSE(DecideResumption(ArcPosition()).next);
  EXPECT_FALSE(DecideResumption(ArcPosition()).previous);
}

TEST(GeometryUsable, GatesOnSigmaP) {
  EXPECT_TRUE(GeometryUsable(Geometry(Rigid3d(), 2.0), 4.0));
  EXPECT_FALSE(GeometryUsable(Geometry(Rigid3d(), 4.5), 4.0));
  EXPECT_FALSE(GeometryUsable(Geometry(Rigid3d(), 1.0, /*success=*/false), 4.0));
}

PlacedCamera Placed(double along, double sigma_p = 0.5) {
  ArcPosition position;
  position.valid = true;
  position.along = along;
  position.distance_to_from = std::abs(along);
  position.distance_to_to = std::abs(1.0 - along);
  return PlacedCamera{position, sigma_p};
}

TEST(FuseArcPositions, AbsolutePoseFirstThenTheMotionDecides) {
  // Three steps of 0.15 arc lengths per frame: expected at 0.55 in frame 5.
  const std::optional<ArcProgress> moving(ArcProgress{0.40, 0.15, 4, true, {0.15, 0.15, 0.15}, 3});
  const ContinuityLimits limits{0.75, 0.3};
  const double agreement = 0.1;
  // The absolute pose, when continuous, decides alone.
  FusedArcPosition f = FuseArcPositions(moving, 5, Placed(0.57), Placed(0.50), Placed(0.80), limits, agreement);
  EXPECT_TRUE(f.position.valid && f.continuous && f.via_pose && !f.via_from && !f.via_to);
  EXPECT_DOUBLE_EQ(f.position.along, 0.57);
  // A jumping absolute pose is not believed: of the current geometries' placements the one nearest to where the
  // motion puts the camera is taken (here W_t:a), the other one is too far from it to be averaged.
  f = FuseArcPositions(moving, 5, Placed(1.60), Placed(0.52), Placed(0.70), limits, agreement);
  EXPECT_TRUE(f.position.valid && f.continuous && !f.via_pose && f.via_from && !f.via_to);
  EXPECT_DOUBLE_EQ(f.position.along, 0.52);
  // Two agreeing placements are averaged.
  f = FuseArcPositions(moving, 5, std::nullopt, Placed(0.52), Placed(0.58), limits, agreement);
  EXPECT_TRUE(f.via_from && f.via_to);
  EXPECT_NEAR(f.position.along, 0.55, 1e-12);
  // W_t:b's placement alone: believed near where the motion puts the camera, not 0.4 arc lengths from it.
  f = FuseArcPositions(moving, 5, std::nullopt, std::nullopt, Placed(0.75), limits, agreement);
  EXPECT_TRUE(f.position.valid && f.via_to);
  f = FuseArcPositions(moving, 5, std::nullopt, std::nullopt, Placed(0.95), limits, agreement);
  EXPECT_FALSE(f.position.valid);
  EXPECT_FALSE(f.continuous);
  // Nothing continuous: no position, and the frame is not continuous (a bad frame, no transition).
  f = FuseArcPositions(moving, 5, Placed(2.0), Placed(-0.5), Placed(1.4), limits, agreement);
  EXPECT_FALSE(f.position.valid);
  EXPECT_FALSE(f.continuous);
  // Nothing placed at all: no position, but nothing contradicted the motion either.
  f = FuseArcPositions(moving, 5, std::nullopt, std::nullopt, std::nullopt, limits, agreement);
  EXPECT_FALSE(f.position.valid);
  EXPECT_TRUE(f.continuous);
  // First frame on an arc (no motion known): the lower σ_p decides between the current geometries.
  f = FuseArcPositions(std::nullopt, 5, std::nullopt, Placed(0.3, 2.0), Placed(0.7, 1.0), limits, agreement);
  EXPECT_TRUE(f.via_to && !f.via_from);
  EXPECT_DOUBLE_EQ(f.position.along, 0.7);
}

TEST(PositionContinuous, BelievesSteadyMotionNotJumps) {
  const auto at = [](double along, size_t frame) { return std::optional<ArcProgress>(ArcProgress{along, 0.0, frame, false}); };
  const auto moving = [](double along, double speed, size_t frame) {
    return std::optional<ArcProgress>(ArcProgress{along, speed, frame, true, {speed, speed, speed}, 3});
  };
  const ContinuityLimits limits{0.75, 0.3};
  // Nothing known yet on this arc (after a bootstrap): any position.
  EXPECT_TRUE(PositionContinuous(std::nullopt, 5, 0.8, limits));
  // Speed unknown (first frames on an arc): steady progress, also backwards (noise) and with dropped frames.
  EXPECT_TRUE(PositionContinuous(at(0.30, 4), 5, 0.45, limits));
  EXPECT_TRUE(PositionContinuous(at(0.30, 4), 5, 0.25, limits));
  EXPECT_TRUE(PositionContinuous(at(0.30, 4), 6, 1.05, limits));
  // Right after a transition (0 on the new arc) a geometry from few far features placed the camera at 0.82
  // of the new arc in the simulated town, where the camera covers ~0.17 arc per frame: not believed.
  EXPECT_FALSE(PositionContinuous(at(0.0, 4), 5, 0.82, limits));
  EXPECT_FALSE(PositionContinuous(at(0.72, 4), 5, 2.0, limits));
  EXPECT_FALSE(PositionContinuous(at(0.9, 4), 5, 0.1, limits));
  // A speed from fewer than three steps (right after a bootstrap) is used for the prediction, with the loose limit.
  EXPECT_TRUE(PositionContinuous(ArcProgress{0.17, 0.17, 4, true, {0.17, 0.0, 0.0}, 1}, 5, 0.90, limits));
  // Speed known: the tighter limit around where the speed puts the camera (0.17 + 0.17 = 0.34 here).
  EXPECT_TRUE(PositionContinuous(moving(0.17, 0.17, 4), 5, 0.40, limits));
  EXPECT_TRUE(PositionContinuous(moving(0.17, 0.17, 4), 5, 0.10, limits));
  EXPECT_FALSE(PositionContinuous(moving(0.17, 0.17, 4), 5, 0.70, limits));
  EXPECT_FALSE(PositionContinuous(moving(0.0, 0.17, 4), 5, 0.98, limits));
  // Short arcs (kitti07 at 320 px in turns): the camera covers about one arc per frame, and the position is
  // predicted from the speed, with that motion as the tolerance.
  EXPECT_TRUE(PositionContinuous(moving(0.27, 1.0, 4), 5, 1.50, limits));
  EXPECT_TRUE(PositionContinuous(moving(0.27, 1.0, 4), 7, 3.20, limits));
  EXPECT_FALSE(PositionContinuous(moving(0.95, 0.17, 4), 6, 2.67, limits));
  EXPECT_FALSE(PositionContinuous(moving(0.27, 1.0, 4), 5, 3.50, limits));
  // ... and a camera that stopped is not expected to move on.
  EXPECT_FALSE(PositionContinuous(moving(0.5, 0.0, 4), 5, 1.4, limits));
  EXPECT_FALSE(PositionContinuous(moving(0.5, 0.0, 4), 5, 0.9, limits));
}

TEST(LocalizerOptions, CheckRejectsBadValues) {
  LocalizerOptions options;
  EXPECT_TRUE(options.Check());
  options.next_arc_ratio = 0.0;
  std::string error;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_FALSE(error.empty());
  options = LocalizerOptions();
  options.max_bad_frames = 0;
  EXPECT_FALSE(options.Check());
  options = LocalizerOptions();
  options.max_progress_step = 0.0;
  EXPECT_FALSE(options.Check());
  options = LocalizerOptions();
  options.prediction_skipped_levels = -1;
  EXPECT_FALSE(options.Check());
  options = LocalizerOptions();
  options.transfer_agreement = 0.0;
  EXPECT_FALSE(options.Check());
  options = LocalizerOptions();
  options.pose.min_inliers = 2;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("pose"), std::string::npos) << error;
  options = LocalizerOptions();
  options.retrieval_shortlist = -1;
  EXPECT_FALSE(options.Check());
  options = LocalizerOptions();
  options.retrieval.patch_size = 4;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("retrieval"), std::string::npos) << error;
}

TEST(Localizer, MapWithoutImagesIsBadInput) {
  Map map;
  MapNode node;
  node.id = 0;
  map.AddNode(node);
  class TinyCamera : public CameraModel {
   public:
    TinyCamera() : CameraModel(64, 48) {}
    CameraModelType type() const override { return CameraModelType::kPerspective; }
    std::string model_name() const override { return "tiny"; }
    bool Project(const Vector3d& p, Vector2d* pixel) const override {
      if (p.z() <= 0) return false;
      *pixel = Vector2d(50 * p.x() / p.z() + 32, 50 * p.y() / p.z() + 24);
      return true;
    }
    bool Unproject(const Vector2d& pixel, Vector3d* bearing) const override {
      *bearing = Vector3d((pixel.x() - 32) / 50, (pixel.y() - 24) / 50, 1).normalized();
      return true;
    }
    double FocalLength() const override { return 50; }
    std::unique_ptr<CameraModel> Scaled(double) const override { return Clone(); }
    std::unique_ptr<CameraModel> Clone() const override { return std::make_unique<TinyCamera>(); }
  };
  EXPECT_THROW(Localizer(map, TinyCamera()), InputError);
}

}  // namespace
}  // namespace retrace
