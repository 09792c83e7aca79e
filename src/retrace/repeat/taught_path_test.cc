#include "retrace/repeat/taught_path.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "retrace/camera/perspective_camera.h"
#include "retrace/geometry/essential.h"
#include "retrace/repeat/linear_map_testing.h"

namespace retrace {
namespace {

// Carried scales of an arc whose true scale is `metres_per_unit`, with `window` arcs on each side: every node scale
// and every right fit off by the model's noise, the fits listed in `wrong` ((side, steps), factor) off by `factor`.
std::vector<CarriedScale> MakeChain(double metres_per_unit, int window,
                                    const std::vector<std::pair<std::pair<int, int>, double>>& wrong, unsigned seed) {
  std::mt19937 random(seed);
  std::normal_distribution<double> node_noise(0.0, 0.01), fit_noise(0.0, 0.02);
  std::vector<CarriedScale> chain;
  const auto fit = [&](int side, int steps, double carried_error) {
    double log_scale = std::log(metres_per_unit) + carried_error + fit_noise(random);
    for (const auto& [where, factor] : wrong) {
      if (where.first == side && where.second == steps) log_scale += std::log(factor);
    }
    chain.push_back({log_scale, side, steps, 0.002});
  };
  fit(0, 0, 0.0);
  for (const int side : {+1, -1}) {
    double carried_error = 0.0;  // the node scales' errors accumulate along the way
    for (int steps = 1; steps <= window; ++steps) {
      carried_error += node_noise(random);
      fit(side, steps, carried_error);
    }
  }
  return chain;
}

double MedianOfWindow(const std::vector<CarriedScale>& scales, int window) {
  std::vector<double> values;
  for (const CarriedScale& s : scales) {
    if (s.steps <= window) values.push_back(std::exp(s.log_metres_per_unit));
  }
  std::sort(values.begin(), values.end());
  return values[values.size() / 2];
}

TEST(CombineArcScalesTest, RecoversTheScaleThroughARunOfWrongGroundFits) {
  // The arc's own ground fit and the next two are wrong, all too large: the factors of a run measured on a
  // validation drive (seed108, arcs 54-56).
  const double truth = 2.0;
  const TaughtPathOptions options;
  for (unsigned seed = 1; seed <= 20; ++seed) {
    const std::vector<CarriedScale> chain =
        MakeChain(truth, options.scale_window, {{{0, 0}, 2.75}, {{1, 1}, 1.45}, {{1, 2}, 2.5}}, seed);
    // The median of the arcs within two of it, as before this model, is taken by the run of wrong fits.
    EXPECT_GT(std::abs(MedianOfWindow(chain, 2) / truth - 1), 0.3) << "seed " << seed;
    const CombinedScale combined = CombineArcScales(chain, options);
    ASSERT_TRUE(combined.valid);
    EXPECT_NEAR(combined.metres_per_unit / truth, 1.0, 0.04) << "seed " << seed;
    EXPECT_EQ(combined.inliers, 2 * options.scale_window + 1 - 3) << "seed " << seed;
    EXPECT_GT(combined.sigma, 0.005);
    EXPECT_LT(combined.sigma, options.ground_scale_sigma);
  }
}

TEST(CombineArcScalesTest, WeighsTheNearFitsMostWhenAllAreRight) {
  // Far arcs carry their scale through more node scales. With the fits ahead drifting away (0.4 % per step, all
  // within the right fits' spread) the estimate stays nearer the arc's own fit than the plain mean of the logs.
  const TaughtPathOptions options;
  std::vector<CarriedScale> scales{{0.0, 0, 0, 0.0}};
  double mean = 0.0;
  for (int steps = 1; steps <= options.scale_window; ++steps) {
    scales.push_back({0.004 * steps, +1, steps, 0.0});
    mean += scales.back().log_metres_per_unit / (options.scale_window + 1);
  }
  const CombinedScale combined = CombineArcScales(scales, options);
  ASSERT_TRUE(combined.valid);
  EXPECT_EQ(combined.inliers, options.scale_window + 1);
  EXPECT_GT(std::log(combined.metres_per_unit), 0.0);
  EXPECT_LT(std::log(combined.metres_per_unit), 0.5 * mean);
}

TEST(CombineArcScalesTest, OneFitIsTakenAsItIsAndNoneIsInvalid) {
  const TaughtPathOptions options;
  EXPECT_FALSE(CombineArcScales({}, options).valid);
  const CombinedScale one = CombineArcScales({{std::log(3.0), 0, 0, 0.05}}, options);
  ASSERT_TRUE(one.valid);
  EXPECT_NEAR(one.metres_per_unit, 3.0, 1e-9);
  // The fit's own σ (larger than ground_scale_sigma), over the responsibility of a lone fit (0.995).
  EXPECT_NEAR(one.sigma, 0.05, 1e-3);
}

TEST(TaughtPathOptionsTest, RejectsAScaleOrTravelModelOutOfRange) {
  std::string error;
  EXPECT_TRUE(TaughtPathOptions().Check(&error)) << error;
  // Each option out of its range is refused, and named.
  const std::vector<std::pair<std::string, std::function<void(TaughtPathOptions&)>>> cases = {
      {"relative_scale_sigma", [](TaughtPathOptions& o) { o.relative_scale_sigma = 0.0; }},
      {"ground_outlier_probability", [](TaughtPathOptions& o) { o.ground_outlier_probability = 1.0; }},
      {"ground_scale_sigma", [](TaughtPathOptions& o) { o.ground_scale_sigma = -0.1; }},
      {"travel_window", [](TaughtPathOptions& o) { o.travel_window = -1; }},
      {"travel_min_turn_rad", [](TaughtPathOptions& o) { o.travel_min_turn_rad = 0.0; }},
      {"travel_sigma_rad", [](TaughtPathOptions& o) { o.travel_sigma_rad = -0.001; }},
  };
  for (const auto& [name, spoil] : cases) {
    TaughtPathOptions options;
    spoil(options);
    EXPECT_FALSE(options.Check(&error)) << name;
    EXPECT_NE(error.find(name), std::string::npos) << error;
  }
}

// On a circle the tangents are the circle's, however unevenly the key-images are spaced (Catmull-Rom tangents, the
// directions from the previous to the next key-image, are not: 0.2 rad off at the second key-image here) and
// whatever yaw the camera is mounted with (only the headings' differences count).
TEST(KeyImageTangentsTest, FollowACircleWithUnevenKeyImagesAndAYawedCamera) {
  const double radius = 20.0;
  const std::vector<double> angles = {0.0, 0.1, 0.6, 0.75, 1.2};  // radians along a left turn
  const double mount_yaw = 5.0 * M_PI / 180;
  std::vector<Vector2d> centres, headings, truth;
  for (const double a : angles) {
    centres.emplace_back(-radius + radius * std::cos(a), radius * std::sin(a));  // (right, forward)
    truth.emplace_back(-std::sin(a), std::cos(a));
    headings.emplace_back(-std::sin(a + mount_yaw), std::cos(a + mount_yaw));
  }
  const std::vector<Vector2d> tangents = KeyImageTangents(centres, headings);
  ASSERT_EQ(tangents.size(), centres.size());
  for (size_t i = 0; i < tangents.size(); ++i) EXPECT_LT((tangents[i] - truth[i]).norm(), 1e-9) << i;
  const Vector2d catmull_rom = (centres[2] - centres[0]).normalized();
  EXPECT_GT((catmull_rom - truth[1]).norm(), 0.1);
}

TEST(KeyImageTangentsTest, AStraightRoadKeepsItsDirection) {
  const std::vector<Vector2d> centres = {{0, 0}, {0.3, 4}, {0.6, 8}, {0.9, 12}};
  const std::vector<Vector2d> headings(4, Vector2d(0.2, 1.0));  // a yawed camera, not along the road: no turn
  const Vector2d road = Vector2d(0.3, 4).normalized();
  for (const Vector2d& t : KeyImageTangents(centres, headings)) EXPECT_LT((t - road).norm(), 1e-12);
}


// A car-like vehicle driven along a curvature profile (rear-axle kinematics), its camera `camera_ahead` metres in
// front of the rear axle and yawed by `mount_yaw` on its mount. Ground coordinates (X right, Z ahead at the start,
// y down), angles counter-clockwise (to the left) from +X.
struct VehicleDrive {
  // Driven `length` metres along the profile of Curvature().
  VehicleDrive(double camera_ahead_m, double mount_yaw_rad, double length)
      : camera_ahead(camera_ahead_m), mount_yaw(mount_yaw_rad) {
    Drive(length);
  }
  double camera_ahead = 1.8;
  double mount_yaw = 0.0;
  struct State {
    Vector2d rear;     // rear axle (m)
    double heading;    // vehicle's direction
    double curvature;  // 1/m, positive turning left
  };
  std::vector<State> states;  // every 0.05 m

  // Straight 30 m, a 10 m transition into a left turn of radius 12 m for 12 m, a 10 m transition back, straight 20 m.
  static double Curvature(double s) {
    const double turn = 1.0 / 12.0;
    if (s < 30) return 0.0;
    if (s < 40) return turn * (s - 30) / 10;
    if (s < 52) return turn;
    if (s < 62) return turn * (62 - s) / 10;
    return 0.0;
  }
  void Drive(double length) {
    State state{Vector2d(0, 0), M_PI / 2, 0.0};
    const double ds = 0.05;
    for (double s = 0; s <= length; s += ds) {
      state.curvature = Curvature(s);
      states.push_back(state);
      // Midpoint integration of the rear axle's motion.
      const double mid = state.heading + 0.5 * ds * state.curvature;
      state.rear += ds * Vector2d(std::cos(mid), std::sin(mid));
      state.heading += ds * state.curvature;
    }
  }
  Vector2d CameraAt(size_t i) const {
    const State& st = states[i];
    return st.rear + camera_ahead * Vector2d(std::cos(st.heading), std::sin(st.heading));
  }
  // world_from_camera: camera z along the axis on the ground, y down.
  Rigid3d WorldFromCamera(size_t i) const {
    const double axis = states[i].heading + mount_yaw;
    const double psi = M_PI / 2 - axis;  // the axis turned from +Z towards +X
    Matrix3d rotation;
    rotation.col(0) = Vector3d(std::cos(psi), 0, -std::sin(psi));
    rotation.col(1) = Vector3d(0, 1, 0);
    rotation.col(2) = Vector3d(std::sin(psi), 0, std::cos(psi));
    const Vector2d c = CameraAt(i);
    return Rigid3d(rotation, Vector3d(c.x(), 0, c.y()));
  }
  // The camera's heading error against its own path: its direction of travel turned by atan(l κ) from the vehicle's,
  // its axis by mount_yaw; positive when it looks to the right of its direction of travel.
  double TrueHeadingError(size_t i) const { return std::atan(camera_ahead * states[i].curvature) - mount_yaw; }
};

// A map of the drive with key-images every `spacing` states, each arc's unit its chord, ground fits and node scales
// exact; the arcs listed in `chord_errors` get their translation's direction turned by that angle about the normal
// (their rotation kept): the focus of expansion forward motion determines worst.
Map MapOfDrive(const VehicleDrive& drive, size_t spacing, double camera_height,
               const std::vector<std::pair<int, double>>& chord_errors, std::vector<size_t>* key_states) {
  key_states->clear();
  for (size_t i = 0; i < drive.states.size(); i += spacing) key_states->push_back(i);
  const int arcs = static_cast<int>(key_states->size()) - 1;
  std::vector<double> lengths;
  for (int k = 0; k < arcs; ++k) {
    lengths.push_back((drive.CameraAt((*key_states)[k + 1]) - drive.CameraAt((*key_states)[k])).norm());
  }
  std::vector<double> scales;
  for (int k = 0; k + 1 < arcs; ++k) scales.push_back(lengths[k + 1] / lengths[k]);
  Map map = LinearMap(arcs, scales);
  for (int k = 0; k < arcs; ++k) {
    const Rigid3d b_from_a =
        drive.WorldFromCamera((*key_states)[k + 1]).Inverse() * drive.WorldFromCamera((*key_states)[k]);
    MapArc& arc = *map.MutableArc(k);
    Vector3d centre_b = -(b_from_a.rotation.transpose() * b_from_a.translation) / lengths[k];
    for (const auto& [which, angle] : chord_errors) {
      if (which == k) centre_b = ExpSO3(Vector3d(0, angle, 0)) * centre_b;
    }
    arc.to_from_from = Rigid3d(b_from_a.rotation, -(b_from_a.rotation * centre_b));
    arc.ground_fit = MapArc::GroundFit{camera_height / lengths[k], 0.001};
  }
  return map;
}

TEST(FitTravelModelTest, RecoversTheMountAndTheCameraAheadThroughWrongChords) {
  const VehicleDrive drive(1.4, 0.03, 80.0);
  std::vector<size_t> keys;
  const Map map = MapOfDrive(drive, 80, 1.5, {}, &keys);  // 4 m apart
  std::vector<ArcTravel> arcs;
  for (size_t k = 0; k + 1 < keys.size(); ++k) {
    // The arc's measurements in metres: the chord's angle from a's axis less half the turn, the turn, the length.
    const Vector2d a = drive.CameraAt(keys[k]), b = drive.CameraAt(keys[k + 1]);
    const double axis_a = drive.states[keys[k]].heading + drive.mount_yaw;
    const double turn = drive.states[keys[k + 1]].heading - drive.states[keys[k]].heading;
    const double chord = std::atan2((b - a).y(), (b - a).x());
    const double angle = chord - axis_a - turn / 2;
    arcs.push_back({std::atan2(std::sin(angle), std::cos(angle)), turn, (b - a).norm()});
  }
  // Three chords 3° off, as in long124's arcs 62-65.
  for (const size_t k : {3, 4, 12}) arcs[k].chord_angle += 3.0 * M_PI / 180;
  const TravelModel model = FitTravelModel(arcs, 0.035);
  ASSERT_TRUE(model.valid);
  EXPECT_GT(model.turning_arcs, 3);
  EXPECT_NEAR(model.mount_yaw, drive.mount_yaw, 0.002);
  EXPECT_NEAR(model.camera_ahead, drive.camera_ahead, 0.15);
  // Straight arcs only: the mount alone, camera_ahead 0; no arcs: invalid.
  const TravelModel straight = FitTravelModel({{0.01, 0.0, 4.0}, {0.012, 0.001, 4.0}, {0.011, -0.001, 4.0}}, 0.035);
  EXPECT_TRUE(straight.valid);
  EXPECT_NEAR(straight.mount_yaw, -0.011, 1e-12);
  EXPECT_EQ(straight.camera_ahead, 0.0);
  EXPECT_FALSE(FitTravelModel({}, 0.035).valid);
  EXPECT_TRUE(std::isnan(straight.mount_yaw_sigma));  // three votes: too few for their spread
}

// mount_yaw_sigma is the spread of mount_yaw over drives: straight chords off by 0.1° (σ) in 400 drives of 12 or
// 40 arcs; the standard deviation of the fitted mount yaw against the mean of its σ.
TEST(FitTravelModelTest, MountYawSigmaIsTheSpreadOfTheFit) {
  std::mt19937 random(5);
  const double chord_sigma = 0.1 * M_PI / 180;
  std::normal_distribution<double> chord_error(0.0, chord_sigma);
  for (const int arcs_per_drive : {12, 40}) {
    double sum = 0.0, sum_squares = 0.0, sigma_sum = 0.0;
    const int drives = 400;
    for (int d = 0; d < drives; ++d) {
      std::vector<ArcTravel> arcs;
      for (int k = 0; k < arcs_per_drive; ++k) arcs.push_back({0.02 + chord_error(random), 0.0, 4.0});
      const TravelModel model = FitTravelModel(arcs, 0.035);
      ASSERT_TRUE(std::isfinite(model.mount_yaw_sigma));
      sum += model.mount_yaw;
      sum_squares += model.mount_yaw * model.mount_yaw;
      sigma_sum += model.mount_yaw_sigma;
    }
    const double mean = sum / drives;
    const double spread = std::sqrt(sum_squares / drives - mean * mean);
    EXPECT_NEAR(mean, -0.02, 3 * spread / std::sqrt(drives)) << arcs_per_drive << " arcs";
    EXPECT_NEAR(sigma_sum / drives / spread, 1.0, 0.2) << arcs_per_drive << " arcs";
  }
}

// Over a whole map, in metres: the rig teach reports (a camera 1.4 m ahead of the rear axle, yawed 0.03 rad).
TEST(TaughtPathTest, MapTravelModelGivesTheRigInMetres) {
  const VehicleDrive drive(1.4, 0.03, 80.0);
  std::vector<size_t> keys;
  const Map map = MapOfDrive(drive, 60, 1.5, {{2, 0.05}}, &keys);  // 3 m apart, one chord 3° off
  const PerspectiveCamera camera(320, 240, 250.0, 250.0, 159.5, 119.5);
  TaughtPathOptions options;
  options.camera_height = 1.5;
  options.ground.normal_in_camera = Vector3d(0.0, 1.0, 0.0);
  TaughtPath path(map, camera, options);
  const TravelModel model = path.MapTravelModel();
  ASSERT_TRUE(model.valid);
  EXPECT_EQ(model.straight_arcs + model.turning_arcs, static_cast<int>(keys.size()) - 1);
  EXPECT_NEAR(model.camera_ahead, drive.camera_ahead, 0.15);
  EXPECT_NEAR(model.mount_yaw, drive.mount_yaw, 0.002);
  // Without the camera's height there are no metres.
  options.camera_height = 0.0;
  EXPECT_FALSE(TaughtPath(map, camera, options).MapTravelModel().valid);
}

// The heading error of the taught camera itself, located on its own map, is the angle from its direction of travel
// to its axis, atan(l κ) - mount_yaw: on the straights the travel model gives it through two arcs whose chords are
// 3° off (their rotations right; the chords' tangents are then that far off), in the turn the curve through the
// key-images (a circle there) gives it.
TEST(TaughtPathTest, HeadingErrorFollowsTheVehicleWhereChordsAreWrong) {
  const VehicleDrive drive(1.8, -0.02, 80.0);
  std::vector<size_t> keys;
  const double three_degrees = 3.0 * M_PI / 180;
  const Map map = MapOfDrive(drive, 80, 1.5, {{3, three_degrees}, {4, -three_degrees}}, &keys);
  const PerspectiveCamera camera(320, 240, 250.0, 250.0, 159.5, 119.5);
  TaughtPathOptions options;
  options.camera_height = 1.5;
  options.ground.normal_in_camera = Vector3d(0.0, 1.0, 0.0);
  TaughtPath travel_path(map, camera, options);
  options.travel_window = 0;
  TaughtPath chord_path(map, camera, options);

  const auto turn = [&](size_t j) {
    return std::abs(drive.states[keys[j + 1]].heading - drive.states[keys[j]].heading);
  };
  double worst_travel = 0.0, worst_chord_on_wrong_arcs = 0.0;
  int steady_points = 0, turn_points = 0;
  for (size_t k = 0; k + 1 < keys.size(); ++k) {
    for (const size_t offset : {20, 40, 60}) {  // a quarter, half and three quarters of the arc
      const size_t i = keys[k] + offset;
      // The camera in the arc's reconstruction (its unit the chord): at its true place and rotation.
      Rigid3d current_from_a = drive.WorldFromCamera(i).Inverse() * drive.WorldFromCamera(keys[k]);
      current_from_a.translation /= (drive.CameraAt(keys[k + 1]) - drive.CameraAt(keys[k])).norm();
      const PathPose travel = travel_path.Locate(static_cast<arc_t>(k), current_from_a, nullptr, static_cast<arc_t>(k));
      const PathPose chord = chord_path.Locate(static_cast<arc_t>(k), current_from_a, nullptr, static_cast<arc_t>(k));
      ASSERT_TRUE(travel.valid && chord.valid) << k;
      // In a turn (the arc and both its neighbours turning by travel_min_turn_rad or more) the reference is the
      // curve's tangent alone.
      if (k >= 1 && k + 2 < keys.size() && turn(k - 1) >= options.travel_min_turn_rad &&
          turn(k) >= options.travel_min_turn_rad && turn(k + 1) >= options.travel_min_turn_rad) {
        EXPECT_NEAR(travel.heading_error_rad, chord.heading_error_rad, 1e-12) << k;
        ++turn_points;
      }
      // Steady curvature over the arc and its neighbours: the model's κ at a key-image comes from the mean turns of
      // the arcs on either side.
      bool steady = k >= 1 && k + 2 < keys.size();
      for (size_t j = k - 1; steady && j <= k + 2; ++j) {
        steady = std::abs(VehicleDrive::Curvature(0.05 * keys[j]) - VehicleDrive::Curvature(0.05 * i)) < 1e-9;
      }
      if (!steady) continue;
      ++steady_points;
      const double truth = drive.TrueHeadingError(i);
      worst_travel = std::max(worst_travel, std::abs(travel.heading_error_rad - truth));
      if (k == 3 || k == 4) {
        worst_chord_on_wrong_arcs = std::max(worst_chord_on_wrong_arcs, std::abs(chord.heading_error_rad - truth));
      }
    }
  }
  EXPECT_EQ(steady_points, 3 * 8);  // five arcs of the first straight, one in the turn, two of the last straight
  EXPECT_GE(turn_points, 3 * 3);
  EXPECT_LT(worst_travel, 0.005);  // 0.3°
  EXPECT_GT(worst_chord_on_wrong_arcs, 0.03);
}

}  // namespace
}  // namespace retrace

namespace retrace {
namespace {

// heading_per_lateral is the regression of the heading error on the lateral offset through the pose's covariance.
// With a covariance of rank one, (δω, δC) = (u, v) ξ, the heading and the offset move together as the pose moves
// along (u, v), and the regression is the ratio of their changes — measured here by moving the pose and locating
// it again. A camera 0.4 m right of a straight 3 m arc, turned 0.05 rad, its ground 1.5 m below.
TEST(TaughtPathTest, HeadingPerLateralFollowsThePoseCovariance) {
  Map map = LinearMap(1);
  MapArc& arc = *map.MutableArc(0);
  arc.to_from_from = Rigid3d(Matrix3d::Identity(), Vector3d(0.0, 0.0, -1.0));  // b one unit ahead of a
  arc.ground_fit = MapArc::GroundFit{0.5, 0.005};                              // 3 m per unit
  TaughtPathOptions options;
  options.camera_height = 1.5;
  options.ground.normal_in_camera = Vector3d(0.0, 1.0, 0.0);
  const PerspectiveCamera camera(320, 240, 250.0, 250.0, 159.5, 119.5);
  TaughtPath path(map, camera, options);

  const auto pose_at = [](const Vector3d& centre, const Matrix3d& rotation) {
    return Rigid3d(rotation, -(rotation * centre));
  };
  const Vector3d centre(0.4 / 3.0, 0.0, 0.5);  // units
  const Matrix3d rotation = ExpSO3(Vector3d(0.0, -0.05, 0.0));
  for (const auto& [u, v] : {std::pair{Vector3d(0.0, 1.0, 0.0), Vector3d(-1.0, 0.0, 0.0)},
                             std::pair{Vector3d(0.1, 0.7, 0.2), Vector3d(0.5, 0.2, 0.3)},
                             std::pair{Vector3d(0.0, -0.3, 0.0), Vector3d(2.0, 0.0, 0.4)}}) {
    const PoseCovariance covariance{v * v.transpose(), u * u.transpose(), u * v.transpose()};
    const PathPose located = path.Locate(0, pose_at(centre, rotation), &covariance, 0);
    ASSERT_TRUE(located.valid);
    EXPECT_NEAR(located.lateral_m, 0.4, 1e-9);
    EXPECT_NEAR(located.heading_error_rad, 0.05, 1e-9);  // turned right of the path (about the downward normal)
    const double step = 1e-6;
    const PathPose moved = path.Locate(0, pose_at(centre + step * v, ExpSO3(step * u) * rotation), nullptr, 0);
    ASSERT_TRUE(moved.valid);
    const double expected =
        (moved.heading_error_rad - located.heading_error_rad) / (moved.lateral_m - located.lateral_m);
    EXPECT_NEAR(located.heading_per_lateral, expected, 1e-4 * std::max(1.0, std::abs(expected)));
  }
  // Without a covariance it is unknown.
  EXPECT_EQ(path.Locate(0, pose_at(centre, rotation), nullptr, 0).heading_per_lateral, 0.0);
}

}  // namespace
}  // namespace retrace
