// Unit tests of the placement decisions on synthetic geometry: transition criterion (Segvic 2009 eq. (9)), prudence
// rules (eqs. (7), (8)), σ_p gating, and the placements as measurements of the belief.

#include "retrace/repeat/placement.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

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

TEST(AlongArc, DistancesAlongTheArc) {
  const ArcPosition p = AlongArc(0.8);
  EXPECT_TRUE(p.valid);
  EXPECT_NEAR(p.distance_to_to, 0.2, 1e-12);
  EXPECT_NEAR(p.distance_to_from, 0.8, 1e-12);
  EXPECT_TRUE(DecideResumption(p).next);
  EXPECT_FALSE(AlongArc(std::nan("")).valid);
}

TEST(AlongSigma, ProjectsTheCentreCovarianceOnTheArcDirection) {
  // An arc of length 2 along z: only the z variance counts, in arc lengths.
  const Rigid3d b_from_a = CamFromWorld(Vector3d(0.0, 0.0, 2.0));
  Matrix3d covariance = Matrix3d::Zero();
  covariance.diagonal() << 0.09, 0.04, 0.16;
  EXPECT_NEAR(AlongSigma(covariance, b_from_a), 0.4 / 2.0, 1e-12);
  // A sideways uncertainty does not move the camera along the arc.
  covariance.diagonal() << 1.0, 1.0, 0.0;
  EXPECT_NEAR(AlongSigma(covariance, b_from_a), 0.0, 1e-12);
}

TEST(PlacementModel, MeasurementsCarryTheirUncertainty) {
  const PlacementModel model;
  EXPECT_TRUE(model.Check());
  const Rigid3d b_from_a = CamFromWorld(Vector3d(0.0, 0.0, 1.0));
  AbsolutePose pose;
  pose.success = true;
  pose.covariance_valid = true;
  pose.centre_covariance = Matrix3d::Identity() * 0.04 * 0.04;
  const PlaceMeasurement m = PoseMeasurement(7, AlongArc(0.4), pose, b_from_a, model);
  EXPECT_EQ(m.arc, 7);
  EXPECT_DOUBLE_EQ(m.along, 0.4);
  EXPECT_NEAR(m.sigma, std::hypot(0.04, model.pose_sigma_floor), 1e-12);
  EXPECT_DOUBLE_EQ(m.outlier_probability, model.pose_outlier_probability);
  // Less reliable: the decomposed placements and a verified key-image.
  EXPECT_GT(GeometryMeasurement(7, AlongArc(0.4), model).outlier_probability, m.outlier_probability);
  MapArc arc;
  arc.id = 3;
  arc.from = 10;
  arc.to = 11;
  EXPECT_DOUBLE_EQ(KeyImageMeasurement(arc, 11, 20, model).along, 1.0);
  EXPECT_DOUBLE_EQ(KeyImageMeasurement(arc, 10, 20, model).along, 0.0);
  EXPECT_DOUBLE_EQ(KeyImageMeasurement(arc, 10, 20, model).outlier_range, 20.0);
  PlacementModel bad;
  bad.geometry_outlier_probability = 1.0;
  EXPECT_FALSE(bad.Check());
}

}  // namespace
}  // namespace retrace
