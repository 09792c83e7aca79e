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
  // W_t:b (x_t = R x_b + t) at an arbitrary positive scale, for a camera at `centre` turned by `yaw`.
  Rigid3d CurrentFromB(const Vector3d& centre, double yaw, double scale) const {
    const Rigid3d current_from_a = CamFromWorld(centre, Yaw(yaw));
    Rigid3d current_from_b = current_from_a * b_from_a.Inverse();
    current_from_b.translation *= scale;
    return current_from_b;
  }
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

TEST(PassedArcEnd, FiresExactlyWhenTheCameraCrossesThePlaneThroughB) {
  const SyntheticArc arc;
  // Direction of travel and a lateral direction perpendicular to it.
  const Vector3d travel = arc.centre_b;
  const Vector3d lateral = travel.cross(Vector3d::UnitY()).normalized();
  for (const double lateral_offset : {-0.3, 0.0, 0.4}) {
    for (const double yaw : {-30.0, 0.0, 15.0}) {
      for (const double scale : {0.01, 1.0, 37.0}) {
        const Vector3d before = 0.97 * travel + lateral_offset * lateral;
        const Vector3d after = 1.03 * travel + lateral_offset * lateral;
        EXPECT_FALSE(PassedArcEnd(arc.CurrentFromB(before, yaw, scale), arc.b_from_a))
            << lateral_offset << " " << yaw << " " << scale;
        EXPECT_TRUE(PassedArcEnd(arc.CurrentFromB(after, yaw, scale), arc.b_from_a))
            << lateral_offset << " " << yaw << " " << scale;
      }
    }
  }
  // Far behind a (reversing past the start): not passed.
  EXPECT_FALSE(PassedArcEnd(arc.CurrentFromB(-0.5 * travel, 0, 1), arc.b_from_a));
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

TEST(DecideTransition, ForwardBackwardAndCancelled) {
  const SyntheticArc arc;
  const Vector3d travel = arc.centre_b;
  const auto position = [&](double along) { return LocateOnArc(CamFromWorld(along * travel), arc.b_from_a); };
  const auto from_a = [&](double along, double sigma) {
    return Geometry(CamFromWorld(along * travel), sigma);
  };
  const auto from_b = [&](double along, double sigma) {
    return Geometry(arc.CurrentFromB(along * travel, 5.0, 0.4), sigma);
  };
  const double max_sigma = 4.0, margin = 0.1;
  // Mid-arc: nothing.
  TwoViewGeometry gb = from_b(0.6, 1.0), ga = from_a(0.6, 1.0);
  EXPECT_EQ(DecideTransition(&gb, position(0.6), &ga, arc.b_from_a, max_sigma, margin), 0);
  // Past b with a trustworthy W_t:b: forward.
  gb = from_b(1.02, 1.0);
  ga = from_a(1.02, 1.0);
  EXPECT_EQ(DecideTransition(&gb, position(1.02), &ga, arc.b_from_a, max_sigma, margin), 1);
  // Same, but σ_p of W_t:b too large: cancelled.
  gb = from_b(1.02, 6.0);
  EXPECT_EQ(DecideTransition(&gb, position(1.02), &ga, arc.b_from_a, max_sigma, margin), 0);
  // No W_t:b at all: no forward transition.
  EXPECT_EQ(DecideTransition(nullptr, position(1.02), &ga, arc.b_from_a, max_sigma, margin), 0);
  // Behind a by more than the margin: backward; within the margin: not yet; σ_p too large: cancelled.
  gb = from_b(-0.2, 1.0);
  ga = from_a(-0.2, 1.0);
  EXPECT_EQ(DecideTransition(&gb, position(-0.2), &ga, arc.b_from_a, max_sigma, margin), -1);
  ga = from_a(-0.05, 1.0);
  gb = from_b(-0.05, 1.0);
  EXPECT_EQ(DecideTransition(&gb, position(-0.05), &ga, arc.b_from_a, max_sigma, margin), 0);
  ga = from_a(-0.2, 5.0);
  gb = from_b(-0.2, 1.0);
  EXPECT_EQ(DecideTransition(&gb, position(-0.2), &ga, arc.b_from_a, max_sigma, margin), 0);
}

TEST(PositionContinuous, BelievesSteadyMotionNotJumps) {
  const auto at = [](double along, size_t frame) { return std::optional<ArcProgress>(ArcProgress{along, 0.0, frame, false}); };
  const auto moving = [](double along, double speed, size_t frame) {
    return std::optional<ArcProgress>(ArcProgress{along, speed, frame, true});
  };
  // Nothing known yet on this arc (after a bootstrap): any position.
  EXPECT_TRUE(PositionContinuous(std::nullopt, 5, 0.8, 0.75));
  // Steady progress, also backwards (noise) and with dropped frames.
  EXPECT_TRUE(PositionContinuous(at(0.30, 4), 5, 0.45, 0.75));
  EXPECT_TRUE(PositionContinuous(at(0.30, 4), 5, 0.25, 0.75));
  EXPECT_TRUE(PositionContinuous(at(0.30, 4), 6, 1.05, 0.75));
  // Right after a transition (0 on the new arc) a geometry from few far features placed the camera at 0.82
  // of the new arc in the simulated town, where the camera covers ~0.17 arc per frame: not believed.
  EXPECT_FALSE(PositionContinuous(at(0.0, 4), 5, 0.82, 0.75));
  EXPECT_FALSE(PositionContinuous(moving(0.0, 0.17, 4), 5, 0.98, 0.75));
  EXPECT_FALSE(PositionContinuous(at(0.72, 4), 5, 2.0, 0.75));
  EXPECT_FALSE(PositionContinuous(at(0.9, 4), 5, 0.1, 0.75));
  // Short arcs (kitti07 at 320 px in turns): the camera covers about one arc per frame, and the position is
  // predicted from the speed, with that motion as the tolerance.
  EXPECT_TRUE(PositionContinuous(moving(0.27, 1.0, 4), 5, 1.50, 0.75));
  EXPECT_TRUE(PositionContinuous(moving(0.27, 1.0, 4), 7, 3.20, 0.75));
  EXPECT_FALSE(PositionContinuous(moving(0.95, 0.17, 4), 6, 2.67, 0.75));
  EXPECT_FALSE(PositionContinuous(moving(0.27, 1.0, 4), 5, 3.50, 0.75));
  // ... and a camera that stopped is not expected to move on.
  EXPECT_FALSE(PositionContinuous(moving(0.5, 0.0, 4), 5, 1.4, 0.75));
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
