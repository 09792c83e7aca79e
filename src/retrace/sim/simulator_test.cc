#include "retrace/sim/simulator.h"

#include <cmath>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "retrace/dataset/ground_truth.h"
#include "retrace/sim/recording.h"
#include "retrace/sim/scenario_io.h"
#include "retrace/util/error.h"
#include "retrace/util/testing.h"

namespace retrace {
namespace {

Scenario SmallTown() {
  Scenario s;
  s.town.blocks_x = 2;
  s.town.blocks_y = 2;
  s.camera.width = 160;
  s.camera.height = 120;
  s.route.segments = 3;
  return s;
}

Matrix34d ReadP0(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::string tag;
  in >> tag;
  Matrix34d p;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) in >> p(r, c);
  }
  return p;
}

// Ground truth through the written files: markers at known world points, seen at night (only the markers glow),
// must appear where poses.txt and calib.txt project them.
TEST(SimulatorTest, WrittenPosesAndCalibrationAgreeWithTheRenderedViews) {
  Scenario s = SmallTown();
  s.camera.width = 320;
  s.camera.height = 240;
  s.num_frames = 8;
  s.town.num_pedestrians = 0;
  s.town.num_moving_cars = 0;
  s.lighting.sun_elevation_deg = -10.0;
  s.lighting.sky_irradiance = 0.0;
  s.sensor.noise_sigma = 0.0;
  s.render.antialiasing = 4;
  s.drive.wobble_amplitude = 0.3;  // the camera also moves sideways and turns a little
  s.marker_radius = 0.12;
  s.markers = {{-2.0, -2.2, 12.0}, {2.0, -3.0, 16.0}, {-1.0, -4.0, 20.0}, {0.5, -1.0, 24.0}, {1.5, -3.6, 30.0}};
  const std::filesystem::path dir = testing::MakeTempDir("sim_poses");
  Simulator sim(s);
  RecordOptions options;
  options.progress = false;
  const RecordSummary summary = RecordSequence(&sim, dir, options);
  ASSERT_EQ(summary.frames, 8);

  std::vector<Rigid3d> poses;
  for (const TimedPose& p : ReadKittiPoses(dir / "poses.txt", dir / "times.txt")) poses.push_back(p.world_from_cam);
  ASSERT_EQ(poses.size(), 8u);
  const Matrix34d p0 = ReadP0(dir / "calib.txt");
  // The first pose is near identity: the camera height above the ground origin and its tilt.
  EXPECT_NEAR(poses[0].translation.y(), -s.vehicle.camera_height, 0.35);
  EXPECT_LT(RotationErrorDeg(poses[0].rotation, Matrix3d::Identity()), s.vehicle.camera_tilt_deg + 3.0);
  int checked = 0;
  double max_error = 0.0;
  for (int f = 0; f < 8; ++f) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.png", f);
    const cv::Mat image = cv::imread((dir / "image_0" / name).string(), cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(image.empty());
    const Rigid3d cam_from_world = poses[f].Inverse();
    std::vector<Vector2d> predicted;
    for (const Vector3d& x : s.markers) predicted.push_back((p0 * (cam_from_world * x).homogeneous()).hnormalized());
    for (size_t m = 0; m < s.markers.size(); ++m) {
      const Vector3d h = p0 * (cam_from_world * s.markers[m]).homogeneous();
      const Vector2d expected = h.hnormalized();
      if (h.z() <= 0 || expected.x() < 8 || expected.y() < 8 || expected.x() > 311 || expected.y() > 231) continue;
      bool crowded = false;  // another marker inside the centroid window
      for (size_t o = 0; o < predicted.size(); ++o) crowded |= o != m && (predicted[o] - expected).norm() < 18.0;
      if (crowded) continue;
      double sx = 0, sy = 0, sw = 0;
      for (int y = static_cast<int>(expected.y()) - 7; y <= static_cast<int>(expected.y()) + 8; ++y) {
        for (int xx = static_cast<int>(expected.x()) - 7; xx <= static_cast<int>(expected.x()) + 8; ++xx) {
          const double w = image.at<uint8_t>(y, xx);
          sx += w * xx;
          sy += w * y;
          sw += w;
        }
      }
      ASSERT_GT(sw, 500.0) << "frame " << f << ": no marker near " << expected.transpose();
      const double error = (Vector2d(sx / sw, sy / sw) - expected).norm();
      EXPECT_LT(error, 0.5) << "frame " << f;
      max_error = std::max(max_error, error);
      ++checked;
    }
  }
  EXPECT_GE(checked, 25);
  std::cout << checked << " marker views, max error " << max_error << " px\n";
}

TEST(SimulatorTest, RepeatVariantHasOtherSunAndOneMetreLateralOffset) {
  Scenario s = SmallTown();
  s.num_frames = 40;
  const Scenario teach = ApplyVariant(s, ScenarioVariant::kTeach);
  const Scenario repeat = ApplyVariant(s, ScenarioVariant::kRepeat);
  EXPECT_NE(teach.lighting.sun_azimuth_deg, repeat.lighting.sun_azimuth_deg);
  EXPECT_NE(teach.lighting.sun_elevation_deg, repeat.lighting.sun_elevation_deg);
  Simulator sim_teach(teach), sim_repeat(repeat);
  std::vector<SimFrame> a, b;
  SimFrame f;
  while (sim_teach.NextFrame(&f)) a.push_back(f);
  while (sim_repeat.NextFrame(&f)) b.push_back(f);
  ASSERT_EQ(a.size(), 40u);
  ASSERT_EQ(b.size(), 40u);
  // Both in the same world frame: the first street runs along world z, so the sideways offset is the difference
  // of the camera centres' x (right) at equal distance along the street.
  std::vector<double> offsets;
  for (const SimFrame& r : b) {
    const Vector3d cr = r.world_from_cam.translation;
    if (cr.z() > 30.0) break;  // stay on the first straight street
    // Teach camera centre at the same z (interpolated).
    for (size_t k = 0; k + 1 < a.size(); ++k) {
      const Vector3d c0 = a[k].world_from_cam.translation, c1 = a[k + 1].world_from_cam.translation;
      if (c0.z() <= cr.z() && cr.z() < c1.z()) {
        const double t = (cr.z() - c0.z()) / (c1.z() - c0.z());
        offsets.push_back(cr.x() - (c0.x() + t * (c1.x() - c0.x())));
        break;
      }
    }
  }
  ASSERT_GE(offsets.size(), 5u);
  double mean = 0.0;
  for (double o : offsets) mean += o / offsets.size();
  EXPECT_NEAR(mean, 1.0, 0.3);  // 1 m to the right, +- the wobble of 0.25 m
  // The images differ (other light, other place).
  EXPECT_GT(std::abs(cv::mean(a[0].image)[0] - cv::mean(b[0].image)[0]), 2.0);
}

// The world frame of a recorded drive in the town frame, without building the town, is the simulator's.
TEST(SimulatorTest, TownFromWorldWithoutTheTownIsTheSimulators) {
  for (const char* route : {"auto", "junctions", "loop"}) {
    Scenario scenario = SmallTown();
    scenario.town.seed = 17;
    scenario.route.type = route;
    scenario.route.junctions = {{{2, 0}}, {{2, 1}}, {{1, 1}}};
    scenario.route.loop_i0 = 0;
    scenario.route.loop_j0 = 0;
    scenario.route.loop_i1 = 1;
    scenario.route.loop_j1 = 1;
    const Rigid3d expected = Simulator(scenario).town_from_world();
    const Rigid3d town_from_world = TownFromWorld(scenario);
    EXPECT_TRUE(town_from_world.rotation.isApprox(expected.rotation, 1e-12)) << route;
    EXPECT_LT((town_from_world.translation - expected.translation).norm(), 1e-9) << route;
  }
}

TEST(SimulatorTest, BicycleModelDrivesCirclesOfRadiusWheelbaseOverTanSteering) {
  VehicleOptions options;
  Vehicle vehicle(options, VehicleState());
  const double steering = 0.2;
  const double radius = options.wheelbase / std::tan(steering);
  // Half a circle: the car ends 2 r to the left, heading backwards.
  const double half = M_PI * radius;
  for (int k = 0; k < 100; ++k) vehicle.Step(steering, half / 10.0, 0.1);
  EXPECT_NEAR(vehicle.state().position.x(), 0.0, 1e-6);
  EXPECT_NEAR(vehicle.state().position.y(), 2.0 * radius, 1e-6);
  EXPECT_NEAR(std::abs(vehicle.state().heading), M_PI, 1e-6);
  // The camera: at the configured height, looking forward (+x of the town at heading 0) and tilted down.
  Vehicle straight(options, VehicleState());
  const Rigid3d town_from_cam = straight.TownFromCamera();
  EXPECT_NEAR(town_from_cam.translation.z(), options.camera_height, 1e-12);
  const Vector3d forward = town_from_cam.rotation.col(2);
  EXPECT_GT(forward.x(), 0.99);
  EXPECT_NEAR(forward.z(), -std::sin(options.camera_tilt_deg * M_PI / 180.0), 1e-12);
}

TEST(SimulatorTest, SpeedProfileSlowsDownInTurns) {
  DriveOptions drive;
  const RoutePath path({{0, 0}, {60, 0}, {60, 60}}, drive);
  EXPECT_NEAR(path.Speed(20.0), drive.max_speed, 1e-9);
  const double turn = path.Project(Vector2d(60 - 2.1, 2.1), 0.0, path.length());  // middle of the rounded corner
  const double expected = std::sqrt(drive.max_lateral_acceleration * drive.corner_radius);
  EXPECT_NEAR(path.Speed(turn), expected, 0.3);
  EXPECT_LT(path.Speed(turn), 0.5 * drive.max_speed);
  // Braking before the turn is limited by max_deceleration: 10 m before the corner the car is still faster.
  EXPECT_GT(path.Speed(turn - 12.0), path.Speed(turn) + 1.0);
  // The autopilot follows the route within a few decimetres.
  Scenario s = SmallTown();
  s.camera.width = 32;
  s.camera.height = 24;
  Simulator sim(s);
  SimFrame f;
  double worst = 0.0;
  int frames = 0;
  while (sim.NextFrame(&f)) {
    const double along = sim.route().Project(f.vehicle.position, 0.0, sim.route().length());
    worst = std::max(worst, (sim.route().Position(along) - f.vehicle.position).norm());
    ++frames;
  }
  EXPECT_GT(frames, 50);
  EXPECT_LT(worst, 0.6);
}

TEST(SimulatorTest, SteppingApiDrivesTheCarAndRendersWhatItSees) {
  Scenario s = SmallTown();
  s.camera.width = 64;
  s.camera.height = 48;
  Simulator sim(s);
  const VehicleState start = sim.vehicle_state();
  // Straight ahead for 1 s at 5 m/s: 5 m along the heading, the camera pose moves with it.
  const SimFrame a = sim.Step(0.0, 5.0, 1.0);
  EXPECT_NEAR((a.vehicle.position - start.position).norm(), 5.0, 1e-9);
  EXPECT_NEAR(a.vehicle.heading, start.heading, 1e-12);
  EXPECT_NEAR(a.timestamp, 1.0, 1e-12);
  EXPECT_EQ(a.image.size(), cv::Size(64, 48));
  // Steering left turns the car left (heading grows) as the bicycle model says.
  const SimFrame b = sim.Step(0.1, 5.0, 1.0);
  EXPECT_NEAR(b.vehicle.heading - a.vehicle.heading, 5.0 * std::tan(0.1) / s.vehicle.wheelbase, 1e-9);
  // The returned pose is the one rendered: rendering it again gives the same image (no noise).
  Scenario quiet = s;
  quiet.sensor.noise_sigma = 0.0;
  Simulator sim2(quiet);
  const SimFrame c = sim2.Step(0.0, 5.0, 1.0);
  const cv::Mat again = sim2.RenderAt(c.world_from_cam, c.timestamp);
  EXPECT_EQ(cv::norm(c.image, again, cv::NORM_L1), 0.0);
}

// Pixels of `a` and `b` (grey, same size) that differ by more than 8 grey levels, as a mask.
cv::Mat Differing(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat difference;
  cv::absdiff(a, b, difference);
  return difference > 8;
}

double Fraction(const cv::Mat& mask) { return static_cast<double>(cv::countNonZero(mask)) / mask.total(); }

// Escorts (vehicle.escorts, Booij 2007 §B.5.4): people walking with the car close to the camera. In a panorama
// without noise and shadows, what they change against the same view without them is their bodies: four block a
// large part of the view (the paper's Figure B.7), both where the car starts (RenderAt) and after it was steered
// 20 m on through a turn (Step, the closed loop): they walk with the camera rather than stay where they started.
// One escort stands on the left of the camera, and sways with its stride.
TEST(SimulatorTest, EscortsWalkBesideTheCameraAndBlockPartOfThePanorama) {
  Scenario s = SmallTown();
  s.camera.model = "equirectangular";
  s.camera.width = 320;
  s.camera.height = 160;
  s.town.num_pedestrians = 0;
  s.town.num_moving_cars = 0;
  s.sensor.noise_sigma = 0.0;
  s.render.antialiasing = 1;
  s.render.shadows = false;
  Scenario one = s, four = s;
  one.vehicle.escorts = 1;
  four.vehicle.escorts = 4;
  Simulator alone(s), with_one(one), with_four(four);
  EXPECT_EQ(alone.scene().num_carried_objects(), 0u);
  EXPECT_EQ(with_four.scene().num_carried_objects(), 4u);
  EXPECT_EQ(with_four.scene().num_moving_objects(), 4u);

  // At the start.
  const SimFrame start = alone.Step(0.0, 0.0, 0.0);
  const cv::Mat blocked_start = Differing(start.image, with_four.RenderAt(start.world_from_cam, start.timestamp));
  // 20 m on, turning left (the same commands give every simulator the same pose).
  const SimFrame on = alone.Step(0.05, 5.0, 4.0);
  const SimFrame on_four = with_four.Step(0.05, 5.0, 4.0);
  ASSERT_LT((on.town_from_cam.translation - on_four.town_from_cam.translation).norm(), 1e-9);
  EXPECT_GT((on.town_from_cam.translation - start.town_from_cam.translation).norm(), 19.0);
  EXPECT_GT(RotationErrorDeg(on.town_from_cam.rotation, start.town_from_cam.rotation), 15.0);
  const cv::Mat blocked_on = Differing(on.image, on_four.image);
  std::cout << "four escorts block " << Fraction(blocked_start) << " of the panorama at the start, "
            << Fraction(blocked_on) << " 20 m on\n";
  EXPECT_GT(Fraction(blocked_start), 0.12);
  EXPECT_GT(Fraction(blocked_on), 0.12);
  EXPECT_NEAR(Fraction(blocked_on), Fraction(blocked_start), 0.03);

  // Escort 0 stands on the camera's left: nearly every pixel it blocks looks left (camera x < 0) and at most 45
  // degrees up (a body up to 1.9 m tall, 0.6 m away from a camera 1.5 m up).
  const cv::Mat image_one = with_one.RenderAt(start.world_from_cam, start.timestamp);
  const cv::Mat blocked_one = Differing(start.image, image_one);
  EXPECT_GT(Fraction(blocked_one), 0.03);
  int left = 0, total = 0;
  for (int v = 0; v < blocked_one.rows; ++v) {
    for (int u = 0; u < blocked_one.cols; ++u) {
      if (!blocked_one.at<uint8_t>(v, u)) continue;
      Vector3d ray;
      ASSERT_TRUE(alone.camera().Unproject(Vector2d(u, v), &ray));
      ++total;
      if (ray.x() < 0.0 && ray.y() > -0.7 * ray.norm()) ++left;
    }
  }
  EXPECT_GT(left, 0.95 * total);
  // Walking, not rigid: a third of a stride later the same view differs along the body's outline.
  const double later = Fraction(Differing(image_one, with_one.RenderAt(start.world_from_cam, start.timestamp + 0.35)));
  EXPECT_GT(later, 0.001);
  EXPECT_LT(later, Fraction(blocked_one));
}

TEST(SimulatorTest, ScenarioFileErrorsNameTheKeyAndLine) {
  try {
    ParseScenario("seed: 3\ncamera:\n  model: perspective\n  width: wide\n", "bad.yaml");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.yaml: line 4: camera.width"), std::string::npos) << e.what();
  }
  try {
    ParseScenario("seed: 3\nroute:\n  typo: 1\n", "bad.yaml");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("line 3: route.typo: unknown key"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ParseScenario("camera: [1, 2\n", "bad.yaml"), InputError);
  EXPECT_THROW(ParseScenario("camera:\n  model: fisheye\n", "bad.yaml"), InputError);
  EXPECT_THROW(ReadScenario("/nonexistent/scenario.yaml"), InputError);
}

TEST(SimulatorTest, ScenarioRoundTripsThroughYaml) {
  Scenario s;
  s.seed = 7;
  s.town.seed = 11;
  s.town.blocks_x = 3;
  s.camera.model = "equirectangular";
  s.camera.width = 400;
  s.camera.height = 200;
  s.camera.distortion.k1 = -0.2;
  s.route.type = "waypoints";
  s.route.waypoints = {{1, 2}, {30, 2.5}};
  s.drive.lateral_offset = 0.4;
  s.lighting.sun_azimuth_deg = 210;
  s.sensor.color = true;
  s.render.num_threads = 1;
  s.render.edge_contrast = 9.5;
  s.repeat.lateral_offset = -1.0;
  s.markers = {{1, -2, 10}};
  const Scenario r = ParseScenario(ScenarioToYaml(s), "round trip");
  EXPECT_EQ(r.seed, 7u);
  EXPECT_EQ(r.town.seed, 11u);
  EXPECT_EQ(r.town.blocks_x, 3);
  EXPECT_EQ(r.camera.model, "equirectangular");
  EXPECT_EQ(r.camera.width, 400);
  EXPECT_DOUBLE_EQ(r.camera.distortion.k1, -0.2);
  EXPECT_EQ(r.route.type, "waypoints");
  ASSERT_EQ(r.route.waypoints.size(), 2u);
  EXPECT_DOUBLE_EQ(r.route.waypoints[1].y(), 2.5);
  EXPECT_DOUBLE_EQ(r.drive.lateral_offset, 0.4);
  EXPECT_DOUBLE_EQ(r.lighting.sun_azimuth_deg, 210);
  EXPECT_TRUE(r.sensor.color);
  EXPECT_EQ(r.render.num_threads, 1);
  EXPECT_DOUBLE_EQ(r.render.edge_contrast, 9.5);
  EXPECT_DOUBLE_EQ(r.repeat.lateral_offset, -1.0);
  ASSERT_EQ(r.markers.size(), 1u);
  EXPECT_DOUBLE_EQ(r.markers[0].z(), 10.0);
}

// Issue 18: frames beyond the route's end. The autopilot stops at the end of the route whatever the frame count
// (as frames 0 does) and the recording says how many frames it wrote instead of driving on out of the town.
TEST(SimulatorTest, RecordingStopsAtTheRouteEndAndSaysHowManyFramesItWrote) {
  Scenario s = SmallTown();
  s.camera.width = 32;
  s.camera.height = 24;
  s.town.num_pedestrians = 0;
  s.town.num_moving_cars = 0;
  s.route.segments = 1;  // one street: about 60 m, some 80 frames
  RecordOptions options;
  options.progress = false;

  Simulator whole(s);
  const int route_frames = whole.ExpectedFrames();
  const RecordSummary all = RecordSequence(&whole, testing::MakeTempDir("sim_route_whole"), options);
  EXPECT_FALSE(all.stopped_at_route_end);  // nothing was asked for beyond the route
  EXPECT_TRUE(whole.RouteFinished());
  EXPECT_NEAR(all.frames, route_frames, 0.05 * route_frames);

  s.num_frames = 10 * all.frames;
  Simulator beyond(s);
  EXPECT_LE(beyond.ExpectedFrames(), route_frames);
  const std::filesystem::path dir = testing::MakeTempDir("sim_route_beyond");
  const RecordSummary summary = RecordSequence(&beyond, dir, options);
  EXPECT_EQ(summary.frames, all.frames);
  EXPECT_EQ(summary.frames_requested, s.num_frames);
  EXPECT_TRUE(summary.stopped_at_route_end);
  EXPECT_NEAR(summary.driven_m, summary.route_length_m, 1.0);
  // The written poses end at the route's end: the last one is within a frame's travel of it.
  const std::vector<TimedPose> poses = ReadKittiPoses(dir / "poses.txt", dir / "times.txt");
  ASSERT_EQ(poses.size(), static_cast<size_t>(summary.frames));
  const Vector2d end = beyond.route().Position(beyond.route().length());
  const Rigid3d town_from_cam = beyond.town_from_world() * poses.back().world_from_cam;
  EXPECT_LT((town_from_cam.translation.head<2>() - end).norm(), 5.0);

  // Fewer frames than the route: exactly those, not stopped at the end.
  s.num_frames = all.frames / 2;
  Simulator part(s);
  const RecordSummary half = RecordSequence(&part, testing::MakeTempDir("sim_route_half"), options);
  EXPECT_EQ(half.frames, s.num_frames);
  EXPECT_FALSE(half.stopped_at_route_end);
  EXPECT_FALSE(part.RouteFinished());
}

// The closed loop's bound: a car steered straight on where the route turns (a lost controller) leaves the route,
// which the simulator reports, as it does past the route's end.
TEST(SimulatorTest, CarDrivingOffTheRouteIsOffRoute) {
  Scenario s = SmallTown();
  s.camera.width = 16;
  s.camera.height = 12;
  s.route.type = "waypoints";
  s.route.waypoints = {{0.0, 0.0}, {40.0, 0.0}, {40.0, 40.0}};  // east, then a left turn north
  Simulator straight(s);
  EXPECT_FALSE(straight.OffRoute());
  int frames = 0;
  while (!straight.OffRoute() && frames < 200) {
    straight.Step(0.0, 5.0, 0.2);
    ++frames;
  }
  EXPECT_TRUE(straight.OffRoute());
  // Off by more than 20 m from the route: beyond the turn, about 60 m along the first street (at 1 m per frame).
  EXPECT_GT(frames, 45);
  EXPECT_LT(frames, 90);

  // Following the route to its end: off route there, not before.
  Simulator follower(s);
  SimFrame frame;
  int driven = 0;
  for (bool off = follower.OffRoute(); follower.NextFrame(&frame); off = follower.OffRoute()) {
    EXPECT_FALSE(off) << "frame " << driven;
    ++driven;
  }
  EXPECT_GT(driven, 10);
  EXPECT_TRUE(follower.OffRoute());
}

// A scenario built in code is checked too: no simulator with 100000 render threads.
TEST(SimulatorTest, RefusesAScenarioOutsideItsRanges) {
  Scenario s = SmallTown();
  s.render.num_threads = 100000;
  try {
    Simulator simulator(s);
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "Simulator: invalid scenario: render.threads: must be in 1..256, got 100000");
  }
}

}  // namespace
}  // namespace retrace

namespace retrace {
namespace {

// route.type junctions: the car drives through the listed junctions in the right lane, straight through (1, 0) and
// turning left at (2, 0).
TEST(SimulatorTest, JunctionsRouteDrivesThroughTheListedJunctions) {
  Scenario scenario;
  scenario.town.blocks_x = 3;
  scenario.town.blocks_y = 2;
  scenario.town.num_pedestrians = 0;
  scenario.town.num_moving_cars = 0;
  scenario.route.type = "junctions";
  scenario.route.junctions = {{{0, 0}}, {{1, 0}}, {{2, 0}}, {{2, 1}}};
  const Simulator simulator(scenario);
  const TownLayout& layout = simulator.layout();
  const std::vector<Vector2d> route = ResolveRoute(scenario, layout);
  std::vector<Vector2d> centre;
  for (const auto& [i, j] : scenario.route.junctions) centre.push_back(layout.Junction(i, j));
  const std::vector<Vector2d> expected = OffsetPolyline(centre, layout.lane_offset());
  ASSERT_EQ(route.size(), expected.size());
  for (size_t k = 0; k < route.size(); ++k) EXPECT_LT((route[k] - expected[k]).norm(), 1e-9) << k;
  // East along the street j = 0 in its right (southern) lane, then north along i = 2 in its right (eastern) lane.
  EXPECT_NEAR(route.front().y(), layout.street_y[0] - layout.lane_offset(), 1e-9);
  EXPECT_NEAR(route.back().x(), layout.street_x[2] + layout.lane_offset(), 1e-9);
  EXPECT_GT(route.back().y(), layout.street_y[1] - 1.0);
}

}  // namespace
}  // namespace retrace
