// Unit tests of the placement decisions on synthetic geometry: transition criterion (Segvic 2009 eq. (9)), prudence
// rules (eqs. (7), (8)), σ_p gating, and the placements as measurements of the belief.

#include "retrace/repeat/placement.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "retrace/repeat/linear_map_testing.h"

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

// A route turning left by `turn` degrees at every key-image, key-images 1 apart, seen from above (x right, z
// forward, y down; a left turn is a negative yaw of the travel direction about y). Key-image k's camera looks along
// the route. Returns the pose of key-image k in the frame of key-image 0 as cam_from_world.
Rigid3d TurningKeyImage(int k, double turn) {
  Vector3d centre = Vector3d::Zero();
  double heading = 0.0;  // degrees, yaw of the travel direction
  for (int i = 0; i < k; ++i) {
    centre += Yaw(heading) * Vector3d::UnitZ();
    heading -= turn;
  }
  return CamFromWorld(centre, Yaw(heading));
}

TEST(BisectingBounds, ThePlaneBetweenTwoArcsIsTheSameForBoth) {
  // Three arcs 0 -> 1 -> 2 -> 3 of a route turning 30 degrees at every node. A camera 0.8 arc lengths beside node 2
  // on its bisecting plane: arc (1, 2) says along = 1 exactly when arc (2, 3) says along = 0, whichever side of the
  // route it is on; the perpendicular planes of the paper disagree there.
  const double turn = 30.0;
  const Rigid3d k1 = TurningKeyImage(1, turn), k2 = TurningKeyImage(2, turn), k3 = TurningKeyImage(3, turn);
  const Rigid3d k0 = TurningKeyImage(0, turn);
  const Rigid3d one_from_zero = k1 * k0.Inverse();
  const Rigid3d two_from_one = k2 * k1.Inverse();
  const Rigid3d three_from_two = k3 * k2.Inverse();
  const ArcBounds arc_12 = BisectingBounds(two_from_one, &one_from_zero, &three_from_two);
  const ArcBounds arc_23 = BisectingBounds(three_from_two, &two_from_one, nullptr);
  ASSERT_GT(arc_12.normal_at_to.norm(), 0.5);
  EXPECT_EQ(arc_23.normal_at_to.norm(), 0.0);  // the route's end: the paper's plane
  const Vector3d node2 = CameraCentre(k2);
  const Vector3d bisector_normal =
      (node2 - CameraCentre(k1)).normalized() + (CameraCentre(k3) - node2).normalized();
  const Vector3d across = bisector_normal.cross(Vector3d::UnitY()).normalized();  // in the plane, horizontal
  for (const double offset : {-0.8, 0.0, 0.8}) {
    const Vector3d on_plane = node2 + offset * across;
    // The camera (any heading) in the frames of key-images 1 and 2.
    const Rigid3d camera = CamFromWorld(on_plane, Yaw(-45));
    const ArcPosition on_12 = LocateOnArc(camera * k1.Inverse(), two_from_one, arc_12);
    const ArcPosition on_23 = LocateOnArc(camera * k2.Inverse(), three_from_two, arc_23);
    ASSERT_TRUE(on_12.valid && on_23.valid);
    EXPECT_NEAR(on_12.along, 1.0, 1e-9) << offset;
    EXPECT_NEAR(on_23.along, 0.0, 1e-9) << offset;
    // The paper's planes: outside the turn (offset < 0, right of a left turn) arc (1, 2) is left too early and arc
    // (2, 3) entered too late, inside the other way round, by the offset's component along each chord (the chords
    // are 15 degrees from the bisecting plane's normal).
    const double chord_12 = LocateOnArc(camera * k1.Inverse(), two_from_one).along;
    const double chord_23 = LocateOnArc(camera * k2.Inverse(), three_from_two).along;
    EXPECT_NEAR(chord_12 - 1.0, -offset * std::sin(15.0 * M_PI / 180.0), 1e-9) << offset;
    EXPECT_NEAR(chord_23, offset * std::sin(15.0 * M_PI / 180.0), 1e-9) << offset;
  }
  // On the taught path the bisecting planes place the camera as the paper's at both key-images, and in between
  // within the cosine of the half-turn.
  for (const double along : {0.0, 0.25, 0.5, 0.75, 1.0}) {
    const Vector3d on_path = CameraCentre(k1) + along * (node2 - CameraCentre(k1));
    const double bisecting = LocateOnArc(CamFromWorld(on_path) * k1.Inverse(), two_from_one, arc_12).along;
    EXPECT_NEAR(bisecting, along, 0.02) << along;
    if (along == 0.0 || along == 1.0) {
      EXPECT_NEAR(bisecting, along, 1e-9);
    }
  }
}

TEST(BisectingBounds, BeyondTheArcTheArcsScaleCarriesOn) {
  // kitti07 taught on every 4th frame passes two or three key-images between frames: a camera on the route three
  // key-images past b is placed about three arc lengths ahead (the bisecting fraction alone grows without bound
  // there, as the planes converge), and `along` is continuous across both planes.
  const double turn = 30.0;
  const Rigid3d k0 = TurningKeyImage(0, turn), k1 = TurningKeyImage(1, turn), k2 = TurningKeyImage(2, turn),
                k3 = TurningKeyImage(3, turn), k5 = TurningKeyImage(5, turn);
  const Rigid3d one_from_zero = k1 * k0.Inverse(), two_from_one = k2 * k1.Inverse(), three_from_two = k3 * k2.Inverse();
  const ArcBounds bounds = BisectingBounds(two_from_one, &one_from_zero, &three_from_two);
  const auto along = [&](const Vector3d& centre_in_world) {
    return LocateOnArc(CamFromWorld(centre_in_world) * k1.Inverse(), two_from_one, bounds).along;
  };
  // The key-images lie on a circle of radius R = 1 / (2 sin 15°) whose centre is on every bisecting plane. Key-image
  // 5, three arcs past b (90° around the circle), is R from b's plane, and arc (1, 2)'s direction is 15° from that
  // plane's normal: along = 1 + R / cos 15° = 1 + 1 / sin 30° = 3 exactly.
  EXPECT_NEAR(along(CameraCentre(k5)), 3.0, 1e-9);
  // Continuity across b's plane and a's plane, beside the route on both sides.
  const Vector3d node1 = CameraCentre(k1), node2 = CameraCentre(k2), node3 = CameraCentre(k3);
  const Vector3d normal_b = ((node2 - node1).normalized() + (node3 - node2).normalized()).normalized();
  const Vector3d normal_a = ((node1 - CameraCentre(k0)).normalized() + (node2 - node1).normalized()).normalized();
  for (const double offset : {-0.6, 0.6}) {
    const Vector3d beside_b = node2 + offset * normal_b.cross(Vector3d::UnitY()).normalized();
    EXPECT_NEAR(along(beside_b - 1e-7 * normal_b), 1.0, 1e-5) << offset;
    EXPECT_NEAR(along(beside_b + 1e-7 * normal_b), 1.0, 1e-5) << offset;
    const Vector3d beside_a = node1 + offset * normal_a.cross(Vector3d::UnitY()).normalized();
    EXPECT_NEAR(along(beside_a - 1e-7 * normal_a), 0.0, 1e-5) << offset;
    EXPECT_NEAR(along(beside_a + 1e-7 * normal_a), 0.0, 1e-5) << offset;
  }
}

TEST(InFrontOfStartPlane, TheBootstrapsSideTestUsesTheBisectingPlaneAtAnyScale) {
  // Arc (1, 2) of the route turning 30 degrees at every key-image. A camera 0.8 arc lengths to the right of key-image
  // 1 (outside the turn), just past the bisecting plane there, has entered arc (1, 2); the paper's plane
  // perpendicular to (1, 2) says it has not yet (it is 0.8 sin 15° = 0.21 behind that plane). The test reads the
  // direction of the camera only: a W_t:a known up to scale gives the same answer.
  const double turn = 30.0;
  const Rigid3d k0 = TurningKeyImage(0, turn), k1 = TurningKeyImage(1, turn), k2 = TurningKeyImage(2, turn);
  const Rigid3d one_from_zero = k1 * k0.Inverse(), two_from_one = k2 * k1.Inverse();
  const ArcBounds bounds = BisectingBounds(two_from_one, &one_from_zero, nullptr);
  const Vector3d node0 = CameraCentre(k0), node1 = CameraCentre(k1), node2 = CameraCentre(k2);
  const Vector3d normal_a = ((node1 - node0).normalized() + (node2 - node1).normalized()).normalized();
  const Vector3d right = -normal_a.cross(Vector3d::UnitY()).normalized();
  for (const double past : {0.01, -0.01}) {
    const Vector3d world = node1 + 0.8 * right + past * normal_a;
    const Vector3d centre = (CamFromWorld(world) * k1.Inverse()).Inverse().translation;  // in key-image 1's frame
    for (const double scale : {1.0, 0.2, 7.0}) {
      EXPECT_EQ(InFrontOfStartPlane(scale * centre, two_from_one, bounds), past > 0) << past << " " << scale;
      EXPECT_FALSE(InFrontOfStartPlane(scale * centre, two_from_one)) << past << " " << scale;
    }
  }
}

TEST(BisectingBounds, StraightRoutesAndReversalsKeepThePapersPlane) {
  const Rigid3d step = CamFromWorld(Vector3d(0.0, 0.0, 1.0));
  const ArcBounds straight = BisectingBounds(step, &step, &step);
  EXPECT_NEAR((straight.normal_at_from - Vector3d::UnitZ()).norm(), 0.0, 1e-12);
  EXPECT_NEAR((straight.normal_at_to - Vector3d::UnitZ()).norm(), 0.0, 1e-12);
  const Vector3d centre(0.3, 0.1, 0.4);
  EXPECT_NEAR(LocateOnArc(CamFromWorld(centre), step, straight).along, 0.4, 1e-12);
  // The next arc goes back the way it came (a turning point): no bisector.
  const Rigid3d back = CamFromWorld(Vector3d(0.0, 0.0, -1.0), Yaw(180));
  EXPECT_EQ(BisectingBounds(step, nullptr, &back).normal_at_to.norm(), 0.0);
}

TEST(AlongSigma, FollowsTheGradientBetweenBisectingPlanes) {
  // Numerical gradient of LocateOnArc against the analytic one in AlongSigma, beside a 30-degree turn.
  const double turn = 30.0;
  const Rigid3d k0 = TurningKeyImage(0, turn), k1 = TurningKeyImage(1, turn), k2 = TurningKeyImage(2, turn),
                k3 = TurningKeyImage(3, turn);
  const Rigid3d one_from_zero = k1 * k0.Inverse(), two_from_one = k2 * k1.Inverse(), three_from_two = k3 * k2.Inverse();
  const ArcBounds bounds = BisectingBounds(two_from_one, &one_from_zero, &three_from_two);
  const auto along = [&](const Vector3d& c) { return LocateOnArc(CamFromWorld(c), two_from_one, bounds).along; };
  // Between the planes, past b's, behind a's (centres in key-image 1's frame).
  for (const Vector3d& centre : {Vector3d(0.7, 0.05, 0.6), Vector3d(-0.4, 0.0, 2.2), Vector3d(0.3, -0.1, -0.5)}) {
    for (int axis = 0; axis < 3; ++axis) {
      Matrix3d covariance = Matrix3d::Zero();
      covariance(axis, axis) = 1.0;
      const double h = 1e-6;
      const double numeric =
          (along(centre + h * Vector3d::Unit(axis)) - along(centre - h * Vector3d::Unit(axis))) / (2 * h);
      EXPECT_NEAR(AlongSigma(covariance, two_from_one, centre, bounds), std::abs(numeric), 1e-6)
          << centre.transpose() << " axis " << axis;
    }
  }
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

// The premise of PlacementModel::pose_shared_error_px: tracked positions that share a relative scale error δs (every
// feature δs farther from the optical axis) move the absolute pose along its viewing direction by about δs times the
// depth of its points, whatever their number; and the pose's σ takes it into account.
TEST(PlacementModel, ASharedScaleErrorMovesAPoseOnDistantPointsAlongTheArc) {
  // Points of a facade 28-32 arc lengths ahead of the camera (the arc's key-images 1 apart along z), 40 of them.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> across(-6.0, 6.0), depth(28.0, 32.0);
  std::vector<Vector3d> points, bearings, scaled;
  for (int i = 0; i < 40; ++i) {
    points.emplace_back(across(rng), 0.5 * across(rng), depth(rng));
    bearings.push_back(points.back().normalized());  // camera at the arc's first key-image, looking along it
    // The image 1 % larger about the optical axis: each ray's angle from the axis 1 % larger.
    const double angle = std::atan2(bearings.back().head<2>().norm(), bearings.back().z()) * 1.01;
    const Vector2d direction = bearings.back().head<2>().normalized();
    scaled.emplace_back(direction.x() * std::sin(angle), direction.y() * std::sin(angle), std::cos(angle));
  }
  AbsolutePoseOptions options;
  const double focal = 300.0;
  const AbsolutePose exact = EstimateAbsolutePose(points, bearings, focal, options);
  const AbsolutePose biased = EstimateAbsolutePose(points, scaled, focal, options);
  ASSERT_TRUE(exact.success);
  ASSERT_TRUE(biased.success);
  const Rigid3d b_from_a = CamFromWorld(Vector3d(0.0, 0.0, 1.0));
  const double along_exact = LocateOnArc(exact.cam_from_world, b_from_a).along;
  const double along_biased = LocateOnArc(biased.cam_from_world, b_from_a).along;
  EXPECT_NEAR(along_exact, 0.0, 1e-6);
  // Closer by 1 % of the depth: the points look 1 % larger.
  EXPECT_NEAR(along_biased - along_exact, 0.01 * 30.0, 0.05);
  // The fit explains the scaled rays with almost no residual: its covariance knows nothing of the move ...
  const PlacementModel model;
  const PlaceMeasurement fitted_only = PoseMeasurement(1, AlongArc(along_biased), biased, b_from_a, model);
  EXPECT_LT(fitted_only.sigma, 0.05);
  // ... the spread of its points does: median depth ~30 arc lengths, RMS radius from the axis in pixels.
  const PoseSpread spread = SpreadOfInliers(biased, points, scaled, 1.0, focal);
  EXPECT_NEAR(spread.median_depth, 29.7, 1.0);
  double sum_squares = 0.0;
  for (const Vector3d& b : scaled) sum_squares += std::pow(std::atan2(b.head<2>().norm(), b.z()), 2);
  EXPECT_NEAR(spread.rms_radius_px, focal * std::sqrt(sum_squares / scaled.size()), 1e-9);
  const PlaceMeasurement m = PoseMeasurement(1, AlongArc(along_biased), biased, b_from_a, model, ArcBounds(), spread);
  const double shared = model.pose_shared_error_px / spread.rms_radius_px * spread.median_depth;
  EXPECT_NEAR(m.sigma, std::hypot(fitted_only.sigma, shared), 1e-12);
  // The placement error, 0.3 arc lengths, is within 3 σ of it (and 6 σ or more of the fit alone).
  EXPECT_LT(std::abs(along_biased - along_exact), 3.0 * m.sigma);
  EXPECT_GT(std::abs(along_biased - along_exact), 6.0 * fitted_only.sigma);
}

// A successful pose whose centre has standard deviation `sigma` (arc lengths) along every axis, on as many inliers as
// give it the model's pose_outlier_probability (PoseOutlierProbability).
AbsolutePose PoseWithIsotropicCovariance(double sigma) {
  AbsolutePose pose;
  pose.success = true;
  pose.num_inliers = static_cast<int>(PlacementModel().pose_outlier_inliers);
  pose.covariance_valid = true;
  pose.centre_covariance = Matrix3d::Identity() * sigma * sigma;
  return pose;
}

// A pose on many inliers is rarely wrong (PlacementModel::pose_outlier_inliers, measured over the validation matrix):
// its outlier probability falls with the square of its inliers, within the model's bounds, and is the flat
// pose_outlier_probability when pose_outlier_inliers is 0.
TEST(PlacementModel, APosesOutlierProbabilityFallsWithItsInliers) {
  PlacementModel model;
  EXPECT_DOUBLE_EQ(PoseOutlierProbability(20, model), model.pose_outlier_probability);
  EXPECT_DOUBLE_EQ(PoseOutlierProbability(40, model), model.pose_outlier_probability / 4.0);
  EXPECT_DOUBLE_EQ(PoseOutlierProbability(127, model), model.pose_outlier_min);
  // Few inliers: at most pose_outlier_max (by default the flat value: raising it lost correct frames).
  EXPECT_DOUBLE_EQ(PoseOutlierProbability(6, model), model.pose_outlier_max);
  EXPECT_DOUBLE_EQ(PoseOutlierProbability(0, model), model.pose_outlier_max);
  model.pose_outlier_max = 0.2;
  EXPECT_DOUBLE_EQ(PoseOutlierProbability(10, model), 4.0 * model.pose_outlier_probability);
  EXPECT_DOUBLE_EQ(PoseOutlierProbability(6, model), model.pose_outlier_max);
  // The measurement carries it.
  AbsolutePose pose;
  pose.success = true;
  pose.num_inliers = 9;
  const Rigid3d b_from_a = CamFromWorld(Vector3d(0.0, 0.0, 1.0));
  EXPECT_DOUBLE_EQ(PoseMeasurement(1, AlongArc(0.4), pose, b_from_a, model).outlier_probability,
                   PoseOutlierProbability(9, model));
  model.pose_outlier_inliers = 0.0;
  EXPECT_TRUE(model.Check());
  for (const int n : {0, 9, 20, 127}) EXPECT_DOUBLE_EQ(PoseOutlierProbability(n, model), model.pose_outlier_probability);
  model.pose_outlier_min = 0.0;
  EXPECT_FALSE(model.Check());
  model.pose_outlier_min = 0.3;
  EXPECT_FALSE(model.Check());  // above pose_outlier_max
  model.pose_outlier_min = 0.002;
  model.pose_outlier_max = 1.0;
  EXPECT_FALSE(model.Check());
}

TEST(PlacementModel, MeasurementsCarryTheirUncertainty) {
  const PlacementModel model;
  EXPECT_TRUE(model.Check());
  const Rigid3d b_from_a = CamFromWorld(Vector3d(0.0, 0.0, 1.0));
  const AbsolutePose pose = PoseWithIsotropicCovariance(0.04);
  const PlaceMeasurement m = PoseMeasurement(7, AlongArc(0.4), pose, b_from_a, model);
  EXPECT_EQ(m.arc, 7);
  EXPECT_DOUBLE_EQ(m.along, 0.4);
  EXPECT_NEAR(m.sigma, std::hypot(0.04, model.pose_sigma_floor), 1e-12);
  EXPECT_DOUBLE_EQ(m.outlier_probability, model.pose_outlier_probability);
  // Less reliable: the decomposed placements and a verified key-image.
  EXPECT_GT(GeometryMeasurement(7, AlongArc(0.4), ArcImage::kA, model).outlier_probability, m.outlier_probability);
  // A current geometry is as reliable anywhere within one arc length of its key-image, and mostly wrong beyond:
  // W_t:a placing the camera 1.375 arc lengths past a, W_t:b 1.375 past b or 0.375 behind a (on the path, so 1.375
  // arc lengths from the key-image in both senses: along the arc and in distance).
  const double within = GeometryMeasurement(7, AlongArc(0.9), ArcImage::kA, model).outlier_probability;
  EXPECT_DOUBLE_EQ(within, model.geometry_outlier_probability);
  EXPECT_DOUBLE_EQ(GeometryMeasurement(7, AlongArc(0.1), ArcImage::kB, model).outlier_probability, within);
  const double expected = 1.0 - (1.0 - within) * std::exp(-0.375 / model.geometry_extrapolation_length) *
                                    std::exp(-0.375 / model.geometry_distance_length);
  EXPECT_NEAR(GeometryMeasurement(7, AlongArc(1.375), ArcImage::kA, model).outlier_probability, expected, 1e-12);
  EXPECT_NEAR(GeometryMeasurement(7, AlongArc(2.375), ArcImage::kB, model).outlier_probability, expected, 1e-12);
  EXPECT_NEAR(GeometryMeasurement(7, AlongArc(-0.375), ArcImage::kB, model).outlier_probability, expected, 1e-12);
  EXPECT_GT(expected, 0.75);
  EXPECT_LT(GeometryMeasurement(7, AlongArc(20.0), ArcImage::kB, model).outlier_probability, 1.0);
  // ... and as unreliable when it places the camera far beside the path: W_t:a half way along an arc of unit length
  // but 2 beside it (validation rand1801, 3 m beside arcs of 3 m, started on a W_t:a 3.4 arc lengths from a).
  const Rigid3d arc_b_from_a = CamFromWorld(Vector3d(0.0, 0.0, 1.0));
  const ArcPosition far_beside = LocateOnArc(CamFromWorld(Vector3d(2.0, 0.0, 0.5)), arc_b_from_a);
  ASSERT_TRUE(far_beside.valid);
  EXPECT_NEAR(far_beside.along, 0.5, 1e-12);
  const double far = std::hypot(2.0, 0.5);
  EXPECT_NEAR(GeometryMeasurement(7, far_beside, ArcImage::kA, model).outlier_probability,
              1.0 - (1.0 - within) * std::exp(-(far - 1.0) / model.geometry_distance_length), 1e-12);
  // Within one arc length of the key-image in every direction nothing changes; past the arc's end both factors count.
  EXPECT_DOUBLE_EQ(GeometryMeasurement(7, LocateOnArc(CamFromWorld(Vector3d(0.5, 0.0, 0.5)), arc_b_from_a),
                                       ArcImage::kA, model)
                       .outlier_probability,
                   within);
  const ArcPosition ahead_beside = LocateOnArc(CamFromWorld(Vector3d(1.0, 0.0, 1.25)), arc_b_from_a);
  EXPECT_NEAR(GeometryMeasurement(7, ahead_beside, ArcImage::kA, model).outlier_probability,
              1.0 - (1.0 - within) * std::exp(-0.25 / model.geometry_extrapolation_length) *
                        std::exp(-(std::hypot(1.0, 1.25) - 1.0) / model.geometry_distance_length),
              1e-12);
  PlacementModel along_only = model;
  along_only.geometry_distance_length = 0.0;
  EXPECT_TRUE(along_only.Check());
  along_only.geometry_distance_length = -0.5;
  EXPECT_FALSE(along_only.Check());
  along_only.geometry_distance_length = 0.0;
  EXPECT_DOUBLE_EQ(GeometryMeasurement(7, far_beside, ArcImage::kA, along_only).outlier_probability, within);
  MapArc arc;
  arc.id = 3;
  arc.from = 10;
  arc.to = 11;
  EXPECT_DOUBLE_EQ(KeyImageMeasurement(arc, 11, 20, model).along, 1.0);
  EXPECT_DOUBLE_EQ(KeyImageMeasurement(arc, 10, 20, model).along, 0.0);
  EXPECT_DOUBLE_EQ(KeyImageMeasurement(arc, 10, 20, model).outlier_range, 20.0);
  // On the taught path a verified key-image is good to about half an arc; beside it, it is looser
  // (PlacementModel::key_image_beside_sigma): 0.8 arc lengths aside the measured RMS was 1.35 arc lengths.
  EXPECT_DOUBLE_EQ(KeyImageMeasurement(arc, 10, 20, model).sigma, model.key_image_sigma);
  EXPECT_DOUBLE_EQ(KeyImageMeasurement(arc, 10, 20, model, 0.0).sigma, model.key_image_sigma);
  const double beside = KeyImageMeasurement(arc, 10, 20, model, 0.8).sigma;
  EXPECT_NEAR(beside, std::hypot(model.key_image_sigma, 0.8 * model.key_image_beside_sigma), 1e-12);
  EXPECT_GT(beside, 1.0);
  EXPECT_LT(KeyImageMeasurement(arc, 10, 20, model, 0.2).sigma, beside);
  EXPECT_DOUBLE_EQ(KeyImageMeasurement(arc, 10, 20, model, 0.8).along, 0.0);
  PlacementModel bad;
  bad.geometry_outlier_probability = 1.0;
  EXPECT_FALSE(bad.Check());
  PlacementModel negative;
  negative.key_image_beside_sigma = -1.0;
  EXPECT_FALSE(negative.Check());
}

// Just after a bootstrap (the speed unknown: here anywhere from a quarter arc back to three arcs ahead per frame,
// key-images one teach frame apart) the camera is placed 0.5 along arc 4 by its pose; the next frame, W_t:b alone places it 1.45 arc
// lengths past arc 4's end, on arc 6 (the kind of placement that is mostly wrong,
// PlacementModel::geometry_extrapolation_length). With the outlier probability of a placement within the arc, the
// belief jumps to arc 6 and reports it; with the one beyond, it does not.
TEST(PlacementModel, AnExtrapolatedGeometryDoesNotCarryTheBeliefTwoArcs) {
  const PlacementModel model;
  const auto run = [&](const PlaceMeasurement& extrapolated) {
    PlaceBeliefOptions options;
    options.unknown_speed_min = -0.25;
    options.unknown_speed_max = 3.0;
    PlaceBelief belief(LinearMap(12, {}, 1), options);
    belief.Predict(1);
    belief.Update({{4, 0.5, 0.03, model.pose_outlier_probability}}, 1);
    belief.Predict(1);
    belief.Update({extrapolated}, 2);
    return belief.estimate();
  };
  const PlaceMeasurement modelled = GeometryMeasurement(4, AlongArc(2.45), ArcImage::kB, model);
  const PlaceMeasurement constant{4, 2.45, model.geometry_sigma, model.geometry_outlier_probability};
  const PlaceEstimate with_constant = run(constant);
  EXPECT_EQ(with_constant.arc, 6);
  EXPECT_TRUE(with_constant.tracking);
  const PlaceEstimate with_model = run(modelled);
  EXPECT_FALSE(with_model.tracking && with_model.arc == 6);
}

// A start 3 m beside a route whose key-images are 3 m apart (validation rand1801, frame 2): from a uniform belief
// over the map, a key-image verified by retrieval (the one two ahead of the camera) and a W_t:a that places the
// camera half way along the arc but 3.3 arc lengths beside it. Taken as a geometry near its key-image the two
// concentrate the belief on that arc; with the distance counted the key-image alone leaves it unsure.
TEST(PlacementModel, AGeometryFarBesideItsKeyImageDoesNotMakeAStartConfident) {
  const PlacementModel model;
  const Rigid3d arc_b_from_a = CamFromWorld(Vector3d(0.0, 0.0, 1.0));
  const ArcPosition far_beside = LocateOnArc(CamFromWorld(Vector3d(3.3, 0.0, 0.48)), arc_b_from_a);
  MapArc arc;
  arc.id = 3;
  arc.from = 3;
  arc.to = 4;
  const auto start = [&](const PlacementModel& with) {
    PlaceBelief belief(LinearMap(40, {}, 1), PlaceBeliefOptions());
    belief.Update({GeometryMeasurement(3, far_beside, ArcImage::kA, with), KeyImageMeasurement(arc, 4, 40, with)}, 0);
    return belief.estimate();
  };
  PlacementModel along_only = model;
  along_only.geometry_distance_length = 0.0;
  const PlaceEstimate before = start(along_only);
  EXPECT_EQ(before.arc, 3);
  EXPECT_TRUE(before.tracking);
  const PlaceEstimate now = start(model);
  EXPECT_FALSE(now.tracking);
  EXPECT_LT(now.confidence, 0.7);
}

// The camera rides at the key-images' height. A camera pitched 5 degrees down drives an arc that climbs: the ground's
// normal and the arc are both tilted in the camera frame, and a centre anywhere on the line through the two
// key-images (before, between, beyond them, or beside it on the ground) lies 0 off it; 0.3 arc lengths above it
// lies -0.3 (the normal points down). Its σ is the covariance projected on the normal.
TEST(HeightOffArc, MeasuresTheCentreAlongTheGroundNormalFromTheKeyImagesLine) {
  const double pitch = 5.0 * M_PI / 180.0;
  // y points down in the camera: a camera pitched down sees the ground's normal (down) tilted towards its axis.
  const Vector3d down(0.0, std::cos(pitch), std::sin(pitch));
  const Vector3d forward = Vector3d(0.0, -std::sin(pitch), std::cos(pitch));  // level ground, in the camera
  const Vector3d right(1.0, 0.0, 0.0);
  const Vector3d up_slope = (forward - 0.05 * down).normalized();  // the road climbs 5 %
  const Rigid3d b_from_a = CamFromWorld(up_slope);
  AbsolutePose pose;
  pose.success = true;
  pose.covariance_valid = true;
  pose.centre_covariance = Vector3d(0.01, 0.04, 0.09).asDiagonal();
  for (const double along : {-1.2, 0.0, 0.4, 1.0, 2.3}) {
    for (const double aside : {0.0, 0.8}) {
      pose.cam_from_world = CamFromWorld(along * up_slope + aside * right);
      const PoseDeviation height = HeightOffArc(pose, b_from_a, down);
      ASSERT_TRUE(height.valid);
      EXPECT_NEAR(height.deviation, 0.0, 1e-3) << along << " " << aside;
    }
    pose.cam_from_world = CamFromWorld(along * up_slope - 0.3 * down);
    EXPECT_NEAR(HeightOffArc(pose, b_from_a, down).deviation, -0.3, 0.003) << along;
  }
  // σ: the covariance along the normal (to first order: the chord's own direction is almost perpendicular to it).
  pose.cam_from_world = CamFromWorld(0.5 * up_slope);
  const Vector3d n = down;
  const Vector3d g = n - n.dot(up_slope) * up_slope;
  EXPECT_NEAR(HeightOffArc(pose, b_from_a, down).sigma, std::sqrt(g.dot(pose.centre_covariance * g)), 1e-12);
  // Without a normal given, the arc's own (the localizer's call): the same as passing GroundNormalOfArc.
  EXPECT_DOUBLE_EQ(HeightOffArc(pose, b_from_a).deviation,
                   HeightOffArc(pose, b_from_a, GroundNormalOfArc(b_from_a)).deviation);
  // Without a covariance (or a normal) there is nothing to compare with.
  pose.covariance_valid = false;
  EXPECT_FALSE(HeightOffArc(pose, b_from_a, down).valid);
  pose.covariance_valid = true;
  EXPECT_FALSE(HeightOffArc(pose, b_from_a, Vector3d::Zero()).valid);
}

// The ground's normal from the arc alone: a camera pitched 5 degrees down (no roll) on level ground, driving straight
// or 30 degrees to the side (a turn), sees the ground's normal where the world's down is; always perpendicular to
// the direction of travel, and pointing down.
TEST(GroundNormalOfArc, IsTheCamerasDownAxisPerpendicularToTheDirectionOfTravel) {
  const double pitch = 5.0 * M_PI / 180.0;
  const Vector3d down(0.0, std::cos(pitch), std::sin(pitch));  // the world's down in the pitched camera
  const Vector3d forward(0.0, -std::sin(pitch), std::cos(pitch));
  const Vector3d right(1.0, 0.0, 0.0);
  for (const double yaw_deg : {0.0, 30.0, -30.0}) {
    const double yaw = yaw_deg * M_PI / 180.0;
    const Vector3d travel = std::cos(yaw) * forward + std::sin(yaw) * right;
    const Vector3d normal = GroundNormalOfArc(CamFromWorld(2.0 * travel));
    EXPECT_NEAR((normal - down).norm(), 0.0, 1e-12) << yaw_deg;
  }
  // Climbing: the car pitches with the road, the normal stays perpendicular to the travel.
  const Vector3d climbing = (forward - 0.1 * down).normalized();
  const Vector3d normal = GroundNormalOfArc(CamFromWorld(climbing));
  EXPECT_NEAR(normal.dot(climbing), 0.0, 1e-12);
  EXPECT_NEAR(normal.norm(), 1.0, 1e-12);
  EXPECT_GT(normal.y(), 0.9);
}

// A pose whose centre hovers above the road (the one of repeat_sim_test's drive 2.5 m aside that rested on six
// features found one texture period off: 0.65 arc lengths above the key-images' line with σ 0.15) is taken as an
// outlier; a pose on the line keeps the model's outlier probability, and one a few σ off is doubted in between.
TEST(PlacementModel, APoseOffTheRoadIsAnOutlier) {
  const PlacementModel model;
  const Rigid3d b_from_a = CamFromWorld(Vector3d(0.0, 0.0, 1.0));
  const AbsolutePose pose = PoseWithIsotropicCovariance(0.04);
  const auto outlier = [&](double deviation, double sigma) {
    return PoseMeasurement(2, AlongArc(0.4), pose, b_from_a, model, ArcBounds(), PoseSpread(),
                           PoseDeviation{true, deviation, sigma})
        .outlier_probability;
  };
  // On the line: the model's probability (a pose wrong along the road keeps its height, so no more trust).
  EXPECT_DOUBLE_EQ(outlier(0.0, 0.05), model.pose_outlier_probability);
  EXPECT_GT(outlier(-0.65, 0.15), 0.9);
  const double doubted = outlier(0.3, 0.1);
  EXPECT_GT(doubted, model.pose_outlier_probability);
  EXPECT_LT(doubted, 0.5);
  // The same deviation with a looser pose is less suspicious.
  EXPECT_LT(outlier(-0.65, 0.5), outlier(-0.65, 0.15));
  // Off: the model's probability whatever the height.
  PlacementModel off = model;
  off.pose_height_sigma = 0.0;
  EXPECT_DOUBLE_EQ(PoseMeasurement(2, AlongArc(0.4), pose, b_from_a, off, ArcBounds(), PoseSpread(),
                                   PoseDeviation{true, -0.65, 0.15})
                       .outlier_probability,
                   model.pose_outlier_probability);
  PlacementModel bad = model;
  bad.pose_height_outlier_span = 0.0;
  EXPECT_FALSE(bad.Check());
}

// The lateral offset: a camera 0.4 arc lengths to the right of a straight arc (camera x), anywhere along it, and its
// σ from the covariance along the side axis only.
TEST(LateralOffArc, MeasuresTheCentreToTheRightOfTheKeyImagesLine) {
  const Rigid3d b_from_a = CamFromWorld(Vector3d(0.0, 0.0, 2.0));
  AbsolutePose pose;
  pose.success = true;
  pose.covariance_valid = true;
  pose.centre_covariance = Vector3d(0.03 * 0.03, 0.5, 0.5).asDiagonal();
  for (const double along : {-0.5, 0.2, 1.3}) {
    pose.cam_from_world = CamFromWorld(Vector3d(0.8, 0.1, 2.0 * along));
    const PoseDeviation lateral = LateralOffArc(pose, b_from_a);
    ASSERT_TRUE(lateral.valid);
    EXPECT_NEAR(lateral.deviation, 0.4, 1e-12) << along;
    EXPECT_NEAR(lateral.sigma, 0.03 / 2.0, 1e-12);
  }
  pose.cam_from_world = CamFromWorld(Vector3d(-0.8, 0.0, 1.0));
  EXPECT_NEAR(LateralOffArc(pose, b_from_a).deviation, -0.4, 1e-12);  // left
  pose.covariance_valid = false;
  EXPECT_FALSE(LateralOffArc(pose, b_from_a).valid);
}

// The lane's prediction: recent poses 0.8 to the right, one collapsed onto the path among them, predict 0.8; the
// older ones count less (they are carried further); fewer than two poses judged right predict nothing.
TEST(LanePrediction, CombinesTheRecentPosesAndOutvotesACollapsedOne) {
  const PlacementModel model;
  std::vector<LaneObservation> lane = {
      {0.80, 0.02, 2.0}, {0.82, 0.02, 1.5}, {0.78, 0.02, 1.0}, {0.0, 0.02, 0.3}, {0.81, 0.02, 0.6}};
  const PoseDeviation predicted = LanePrediction(lane, 1.0, model);
  ASSERT_TRUE(predicted.valid);
  EXPECT_NEAR(predicted.deviation, 0.80, 0.03);
  EXPECT_GT(predicted.sigma, 0.0);
  EXPECT_LT(predicted.sigma, 0.1);
  EXPECT_FALSE(LanePrediction({{0.8, 0.02, 1.0}}, 1.0, model).valid);
  EXPECT_FALSE(LanePrediction({}, 1.0, model).valid);
}

// The lane check (hard126 frames 79-90 of the validation matrix: 2.5 m beside the path, the lane 0.8 arc lengths to
// the right, then poses at 0.14 ... -0.23 lagging half an arc): a pose collapsed onto the path has most likely
// collapsed, and its σ along the arc grows to about collapsed_pose_sigma; a pose on the lane keeps its σ; one
// farther out than the lane is not doubted (a pose collapses towards the path), nor is any pose when the lane is on
// the path. Its outlier probability stays the model's either way (a collapsed pose is mostly near the truth).
TEST(PlacementModel, APoseCollapsedOntoThePathBesideTheLaneIsLessCertain) {
  const PlacementModel model;
  const Rigid3d b_from_a = CamFromWorld(Vector3d(0.0, 0.0, 1.0));
  const AbsolutePose pose = PoseWithIsotropicCovariance(0.04);
  const auto collapsed = [&](double lateral, double predicted) {
    return CollapseProbability(LaneCheck{true, lateral, predicted, 0.05}, model);
  };
  EXPECT_GT(collapsed(0.05, 0.8), 0.99);
  EXPECT_GT(collapsed(-0.15, 0.8), 0.99);   // a little past the path
  EXPECT_GT(collapsed(-0.05, -0.8), 0.99);  // beside the lane on the left
  EXPECT_LT(collapsed(0.8, 0.8), 0.01);
  EXPECT_DOUBLE_EQ(collapsed(1.6, 0.8), 0.0);     // farther out
  EXPECT_DOUBLE_EQ(collapsed(0.35, -0.06), 0.0);  // the lane itself collapsed (seed3)
  EXPECT_LT(collapsed(0.1, 0.0), 0.1);            // on the path nothing collapses
  EXPECT_DOUBLE_EQ(CollapseProbability(LaneCheck(), model), 0.0);

  const PlaceMeasurement on_lane =
      PoseMeasurement(2, AlongArc(0.4), pose, b_from_a, model, ArcBounds(), PoseSpread(), PoseDeviation(),
                      CollapseProbability(LaneCheck{true, 0.8, 0.8, 0.05}, model));
  const PlaceMeasurement plain = PoseMeasurement(2, AlongArc(0.4), pose, b_from_a, model);
  EXPECT_NEAR(on_lane.sigma, plain.sigma, 0.01);
  const PlaceMeasurement on_path =
      PoseMeasurement(2, AlongArc(0.4), pose, b_from_a, model, ArcBounds(), PoseSpread(), PoseDeviation(),
                      CollapseProbability(LaneCheck{true, 0.05, 0.8, 0.05}, model));
  EXPECT_NEAR(on_path.sigma, std::hypot(plain.sigma, model.collapsed_pose_sigma), 0.005);
  EXPECT_DOUBLE_EQ(on_path.outlier_probability, model.pose_outlier_probability);
  PlacementModel off = model;
  off.pose_lateral_sigma = 0.0;
  EXPECT_DOUBLE_EQ(PoseMeasurement(2, AlongArc(0.4), pose, b_from_a, off, ArcBounds(), PoseSpread(), PoseDeviation(),
                                   CollapseProbability(LaneCheck{true, 0.05, 0.8, 0.05}, off))
                       .sigma,
                   plain.sigma);
  PlacementModel bad = model;
  bad.lane_window = 0.0;
  EXPECT_FALSE(bad.Check());
  bad = model;
  bad.pose_collapse_probability = 1.0;
  EXPECT_FALSE(bad.Check());
  bad = model;
  bad.lane_outlier_probability = 0.0;
  EXPECT_FALSE(bad.Check());
  bad = model;
  bad.lane_outlier_span = 0.0;
  EXPECT_FALSE(bad.Check());
  bad = model;
  bad.lane_max_poses = 1;  // the lane needs two poses judged right
  EXPECT_FALSE(bad.Check());
}

// A collapse brings a pose nearer the path, not across it (FarSideProbability): with the lane 0.8 arc lengths to the
// right, a pose 0.6 to the left is a wrong pose, and its placement an outlier; one on the lane's side, collapsed or
// not, is not doubted by this check; with the lane on the path (0.02) a pose 0.1 to the left is the lane's noise.
TEST(PlacementModel, APoseAcrossThePathFromTheLaneIsWrong) {
  const PlacementModel model;
  const auto far_side = [&](double lateral, double predicted) {
    return FarSideProbability(LaneCheck{true, lateral, predicted, 0.05}, model);
  };
  EXPECT_GT(far_side(-0.6, 0.8), 0.999);
  EXPECT_GT(far_side(0.6, -0.8), 0.999);  // the lane on the left
  EXPECT_GT(far_side(-0.3, 0.8), 0.99);
  EXPECT_DOUBLE_EQ(far_side(0.05, 0.8), 0.0);  // collapsed on the lane's side
  EXPECT_DOUBLE_EQ(far_side(0.8, 0.8), 0.0);
  EXPECT_DOUBLE_EQ(far_side(1.2, 0.8), 0.0);
  EXPECT_DOUBLE_EQ(far_side(0.56, -0.17), 0.0);  // farther out than the lane, which may have drifted across
  EXPECT_LT(far_side(-0.1, 0.02), 0.01);
  // Nearer the path a collapse onto it explains the pose more: the probability falls as the pose nears the path.
  EXPECT_LT(far_side(-0.05, 0.8), far_side(-0.15, 0.8));
  EXPECT_DOUBLE_EQ(FarSideProbability(LaneCheck(), model), 0.0);
  PlacementModel off = model;
  off.pose_lateral_sigma = 0.0;
  EXPECT_DOUBLE_EQ(FarSideProbability(LaneCheck{true, -0.6, 0.8, 0.05}, off), 0.0);

  const Rigid3d b_from_a = CamFromWorld(Vector3d(0.0, 0.0, 1.0));
  const AbsolutePose pose = PoseWithIsotropicCovariance(0.04);
  const PlaceMeasurement plain = PoseMeasurement(2, AlongArc(0.4), pose, b_from_a, model);
  const PlaceMeasurement across = PoseMeasurement(2, AlongArc(0.4), pose, b_from_a, model, ArcBounds(), PoseSpread(),
                                                  PoseDeviation(), 0.0, far_side(-0.6, 0.8));
  EXPECT_DOUBLE_EQ(across.sigma, plain.sigma);
  EXPECT_GT(across.outlier_probability, 0.99);
  EXPECT_LT(across.outlier_probability, 1.0);  // kept below 1: it must not zero the belief
  EXPECT_DOUBLE_EQ(PoseMeasurement(2, AlongArc(0.4), pose, b_from_a, model, ArcBounds(), PoseSpread(),
                                   PoseDeviation(), 0.0, 0.0)
                       .outlier_probability,
                   model.pose_outlier_probability);
}

// The heading against the path: on a straight arc, a camera yawed 10° to the right (Yaw(10) turns the optical axis
// towards x) heads 10° off the path; on an arc whose key-image b turned 20° the same camera halfway along follows
// the path, and so does one at b turned as b; one yawed 10° to the left there heads 20° to the left of it.
TEST(HeadingOffArc, IsTheYawAgainstThePathTurningAlongTheArc) {
  const double degree = M_PI / 180.0;
  const Rigid3d straight = CamFromWorld(Vector3d(0.0, 0.0, 1.0));
  EXPECT_NEAR(HeadingOffArc(CamFromWorld(Vector3d(0.3, 0.0, 0.5), Yaw(10)), straight, 0.5), 10.0 * degree, 1e-9);
  EXPECT_NEAR(HeadingOffArc(CamFromWorld(Vector3d(0.3, 0.0, 0.5)), straight, 0.5), 0.0, 1e-12);
  const Rigid3d turning = CamFromWorld(Vector3d(0.2, 0.0, 1.0), Yaw(20));
  EXPECT_NEAR(HeadingOffArc(CamFromWorld(Vector3d(0.1, 0.0, 0.5), Yaw(10)), turning, 0.5), 0.0, 1e-9);
  EXPECT_NEAR(HeadingOffArc(CamFromWorld(Vector3d(0.2, 0.0, 1.0), Yaw(20)), turning, 1.0), 0.0, 1e-9);
  EXPECT_NEAR(HeadingOffArc(CamFromWorld(Vector3d(0.1, 0.0, 0.5), Yaw(-10)), turning, 0.5), -20.0 * degree, 1e-9);
}

// The lane carries each pose along its heading: a car steering back onto the path at 0.15 rad, its poses every
// 0.25 arc lengths behind it at 1 + sin(0.15) times their distance, predicts the offset where it is now (1.0), not
// where it was.
TEST(LanePrediction, CarriesEachPoseAlongItsHeading) {
  const PlacementModel model;
  std::vector<LaneObservation> lane;
  for (int k = 1; k <= 6; ++k) {
    const double travelled = 0.25 * k;
    lane.push_back({1.0 + std::sin(0.15) * travelled, 0.01, travelled, -0.15});
  }
  const PoseDeviation predicted = LanePrediction(lane, 1.0, model);
  ASSERT_TRUE(predicted.valid);
  EXPECT_NEAR(predicted.deviation, 1.0, 0.01);
  for (LaneObservation& o : lane) o.heading = 0.0;              // carried straight: the lane lags the car
  EXPECT_GT(LanePrediction(lane, 1.0, model).deviation, 1.03);  // about the nearest pose's own 1.037
}

// Four key-images of a straight route 1 apart (z before a, a at the origin, b, c), a camera 0.6 arc lengths beside
// a, half way to b, turned 4 degrees; points on two facades along the road. Each key-image matched the frame's
// key-points (one per point) with 0.3 px of noise at a focal length of 200 px; in the key-image a wrong match for
// every tenth point.
struct KeyImagesBesideTheCamera {
  std::vector<KeyImageMatches> views;
  Vector3d centre = Vector3d(0.6, 0.0, 0.5);
  Rigid3d current = CamFromWorld(centre, Yaw(4));

  explicit KeyImagesBesideTheCamera(int num_views = 4) {
    std::mt19937 random(7);
    std::uniform_real_distribution<double> along(0.5, 8.0), height(-0.6, 0.3), unit(0.0, 1.0);
    std::normal_distribution<double> noise(0.0, 0.3 / 200.0);
    std::vector<Vector3d> points;
    for (int i = 0; i < 120; ++i) points.emplace_back(i % 2 == 0 ? -1.5 : 1.8, height(random), along(random));
    const auto observe = [&](const Rigid3d& cam_from_world, const Vector3d& point, Vector3d* bearing) {
      const Vector3d in_cam = cam_from_world * point;
      if (!(in_cam.z() > 0.2) || std::abs(in_cam.x() / in_cam.z()) > 0.8) return false;
      *bearing = (in_cam.normalized() + Vector3d(noise(random), noise(random), 0.0)).normalized();
      return true;
    };
    for (int k = 0; k < num_views; ++k) {
      KeyImageMatches view;
      view.key_from_arc = CamFromWorld(Vector3d(0.0, 0.0, k - 1.0));
      for (size_t i = 0; i < points.size(); ++i) {
        Vector3d key_bearing, current_bearing;
        if (!observe(view.key_from_arc, points[i], &key_bearing) || !observe(current, points[i], &current_bearing)) {
          continue;
        }
        if (i % 10 == static_cast<size_t>(k)) {  // a wrong match: another point's bearing
          observe(view.key_from_arc, points[(i + 37) % points.size()], &key_bearing);
        }
        view.current_keypoints.push_back(static_cast<int>(i));
        view.key_bearings.push_back(key_bearing);
        view.current_bearings.push_back(current_bearing);
      }
      views.push_back(std::move(view));
    }
  }
};

TEST(ResectFromKeyImages, PlacesACameraBesideTheKeyImagesFromTheirMatches) {
  const KeyImagesBesideTheCamera scene;
  int points = 0;
  const AbsolutePose pose = ResectFromKeyImages(scene.views, 2.0 / 200.0, 200.0, AbsolutePoseOptions(), &points);
  ASSERT_TRUE(pose.success);
  EXPECT_GT(points, 40);
  EXPECT_LT((CameraCentre(pose.cam_from_world) - scene.centre).norm(), 0.05);
  EXPECT_LT(RotationErrorDeg(pose.cam_from_world.rotation, scene.current.rotation), 0.5);
  // On the arc a -> b half way along, as the camera is.
  const ArcPosition position = LocateOnArc(pose.cam_from_world, scene.views[2].key_from_arc);
  ASSERT_TRUE(position.valid);
  EXPECT_NEAR(position.along, 0.5, 0.05);
}

TEST(ResectFromKeyImages, NeedsAKeyPointMatchedInTwoKeyImages) {
  // One key-image: no point can be triangulated (its relative pose alone does not say how far the camera is).
  const KeyImagesBesideTheCamera scene(1);
  int points = -1;
  EXPECT_FALSE(ResectFromKeyImages(scene.views, 2.0 / 200.0, 200.0, AbsolutePoseOptions(), &points).success);
  EXPECT_EQ(points, 0);
}

TEST(PlacementModel, AResectedPoseIsLooserThanItsCovariance) {
  // VerifiedPoseMeasurement: the pose's σ times verified_pose_sigma_factor, with the floor in quadrature, and at least
  // verified_pose_outlier_probability.
  const KeyImagesBesideTheCamera scene;
  const AbsolutePose pose = ResectFromKeyImages(scene.views, 2.0 / 200.0, 200.0, AbsolutePoseOptions());
  ASSERT_TRUE(pose.success);
  const Rigid3d& b_from_a = scene.views[2].key_from_arc;
  const ArcPosition position = LocateOnArc(pose.cam_from_world, b_from_a);
  PlacementModel model;
  const PlaceMeasurement tracked =
      PoseMeasurement(3, position, pose, b_from_a, model, ArcBounds(), PoseSpread(), HeightOffArc(pose, b_from_a));
  const PlaceMeasurement resected = VerifiedPoseMeasurement(3, position, pose, b_from_a, model);
  EXPECT_EQ(resected.arc, 3);
  EXPECT_DOUBLE_EQ(resected.along, tracked.along);
  EXPECT_NEAR(resected.sigma, std::hypot(3.0 * tracked.sigma, 0.1), 1e-12);
  EXPECT_DOUBLE_EQ(resected.outlier_probability, 0.2);
  model.verified_pose_sigma_factor = 0.5;
  EXPECT_FALSE(model.Check());
}

}  // namespace
}  // namespace retrace
