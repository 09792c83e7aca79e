#include "retrace/control/path_tracking.h"

#include <cmath>
#include <functional>
#include <iostream>
#include <vector>

#include <gtest/gtest.h>

#include "retrace/util/types.h"

namespace retrace {
namespace {

// A path on the ground as a dense polyline (x east, y north), and a kinematic car (bicycle model, rear axle)
// whose camera rides `camera_forward` ahead of the rear axle. The law sees the camera's true lateral offset and
// heading error (positive right), as the metric path would give them.
struct TestPath {
  std::vector<Vector2d> points;

  // Signed offset of `c` (positive right of the direction of travel), the heading error of `direction`, and the
  // path's position (index) of the nearest point.
  void Locate(const Vector2d& c, double heading, double* lateral, double* heading_error, double* index) const {
    double best = std::numeric_limits<double>::infinity();
    for (size_t i = 0; i + 1 < points.size(); ++i) {
      const Vector2d ab = points[i + 1] - points[i];
      const double t = std::clamp((c - points[i]).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
      const Vector2d offset = c - (points[i] + t * ab);
      if (offset.norm() < best) {
        best = offset.norm();
        const Vector2d tangent = ab.normalized();
        *lateral = offset.dot(Vector2d(tangent.y(), -tangent.x()));
        const Vector2d look(std::cos(heading), std::sin(heading));
        *heading_error = std::atan2(tangent.y() * look.x() - tangent.x() * look.y(), tangent.dot(look));
        *index = static_cast<double>(i) + t;
      }
    }
  }
};

// A path from a curvature profile kappa(s) (1/m, positive left), starting at the origin heading +x.
TestPath MakePath(double length, const std::function<double(double)>& kappa) {
  TestPath path;
  Vector2d p = Vector2d::Zero();
  double heading = 0.0;
  const double ds = 0.05;
  for (double s = 0; s <= length; s += ds) {
    path.points.push_back(p);
    heading += kappa(s) * ds;
    p += ds * Vector2d(std::cos(heading), std::sin(heading));
  }
  return path;
}

struct DriveResult {
  std::vector<double> lateral;  // per frame, after the start
  std::vector<double> steered;  // the offset the law steered by (PathTrackingCommand::lateral_m), per command
  std::vector<double> driven;   // metres
  bool reached_end = false;
};

// Drives the car at `speed` with one command per `dt`, the camera starting `start_offset` right of the path's
// start, heading along it.
// `measured` (when given) turns the frame's true offset into the one the law is told, with its σ.
using Measurement = std::function<void(int frame, PathTrackingInput* input)>;
DriveResult Drive(const TestPath& path, double speed, double dt, double start_offset, const PathTrackingOptions& options,
                  double wheelbase = 2.7, const Measurement& measured = nullptr) {
  PathTracker tracker(options);
  // Rear axle such that the camera is start_offset to the right (-y) of the start, heading +x.
  Vector2d rear(-options.camera_forward, -start_offset);
  double heading = 0.0;
  DriveResult result;
  double driven = 0.0;
  for (int frame = 0; frame < 5000; ++frame) {
    const Vector2d camera = rear + options.camera_forward * Vector2d(std::cos(heading), std::sin(heading));
    PathTrackingInput input;
    input.tracking = true;
    input.confidence = 1.0;
    input.metric = true;
    double index = 0;
    path.Locate(camera, heading, &input.lateral_m, &input.heading_error_rad, &index);
    input.dt = dt;
    result.lateral.push_back(input.lateral_m);
    if (measured) measured(frame, &input);
    result.driven.push_back(driven);
    if (index >= path.points.size() - 2) {
      result.reached_end = true;
      break;
    }
    const PathTrackingCommand command = tracker.Update(input);
    result.steered.push_back(command.lateral_m);
    // The simulator's car takes the front-wheel angle atan(L kappa), limited to 35 degrees.
    const double wheels = std::clamp(std::atan(wheelbase * command.curvature), -0.61, 0.61);
    const double kappa = std::tan(wheels) / wheelbase;
    const double v = std::min(speed, command.speed);
    const int steps = 10;
    for (int k = 0; k < steps; ++k) {
      const double step = v * dt / steps;
      rear += step * Vector2d(std::cos(heading), std::sin(heading));
      heading += kappa * step;
      driven += step;
    }
  }
  return result;
}

double MaxAbsAfter(const DriveResult& drive, double skip_m) {
  double worst = 0.0;
  for (size_t i = 0; i < drive.lateral.size(); ++i) {
    if (drive.driven[i] >= skip_m) worst = std::max(worst, std::abs(drive.lateral[i]));
  }
  return worst;
}

// A tracked frame, on the path, with a confident belief and a metric offset, 0.1 s after the previous one.
PathTrackingInput ConfidentFrame() {
  PathTrackingInput input;
  input.tracking = true;
  input.confidence = 1.0;
  input.metric = true;
  input.dt = 0.1;
  return input;
}

PathTrackingOptions FastOptions() {
  PathTrackingOptions options;
  options.max_speed = 8.0;
  options.max_acceleration = 100.0;  // start at speed
  return options;
}

TEST(CameraPointCurvature, SteersTowardsThePathAndMatchesASteadyTurn) {
  PathTrackingOptions options;
  // Right of the path, heading along it: turn left (positive curvature); left of it: turn right.
  EXPECT_GT(CameraPointCurvature(0.5, 0.0, options), 0.0);
  EXPECT_LT(CameraPointCurvature(-0.5, 0.0, options), 0.0);
  // On the path, looking right of it: turn left.
  EXPECT_GT(CameraPointCurvature(0.0, 0.1, options), 0.0);
  // On a turn of curvature k the camera followed exactly looks atan(d k) to the right of the path: the law asks
  // for exactly k.
  const double k = 1.0 / 7.0;
  EXPECT_NEAR(CameraPointCurvature(0.0, std::atan(options.camera_forward * k), options), k, 1e-12);
  EXPECT_NEAR(CameraPointCurvature(0.0, -std::atan(options.camera_forward * k), options), -k, 1e-12);
}

TEST(PathTracker, ARunOfFramesAMetreOffDoesNotTurnTheCar) {
  // A pose on one far facade: seven frames in a row put the camera 1 m left of where it is, sure of themselves (σ 5
  // cm), as seed3's frames 7-13 in the validation matrix; the others see the truth with σ 3 cm. The filtered offset
  // (the frames of the last 20 m carried by the car's motion) takes them for wrong; each frame's own steers the car
  // towards the phantom. (With a 10 m window the seven frames are the majority once the older ones have left it.)
  const TestPath path = MakePath(120.0, [](double) { return 0.0; });
  const auto phantom = [](int frame, PathTrackingInput* input) {
    const bool wrong = frame >= 60 && frame < 67;
    input->lateral_m -= wrong ? 1.0 : 0.0;
    input->lateral_sigma_m = wrong ? 0.05 : 0.03;
  };
  PathTrackingOptions filtered = FastOptions();
  PathTrackingOptions own = FastOptions();
  own.offset.process_sigma = 0.0;
  const DriveResult with_filter = Drive(path, 8.0, 0.1, 0.0, filtered, 2.7, phantom);
  const DriveResult without = Drive(path, 8.0, 0.1, 0.0, own, 2.7, phantom);
  ASSERT_TRUE(with_filter.reached_end);
  ASSERT_TRUE(without.reached_end);
  EXPECT_LT(MaxAbsAfter(with_filter, 0.0), 0.05);
  EXPECT_GT(MaxAbsAfter(without, 0.0), 0.3);
  // The command reports the offset it steered by: with the window, the truth within a few centimetres during the
  // seven frames told 1 m off; without it, each frame's own.
  ASSERT_GT(with_filter.steered.size(), 67u);
  for (int frame = 60; frame < 67; ++frame) {
    EXPECT_NEAR(with_filter.steered[frame], with_filter.lateral[frame], 0.05) << frame;
    EXPECT_NEAR(without.steered[frame], without.lateral[frame] - 1.0, 1e-12) << frame;
  }
}

TEST(PathTracker, ARunOfUncertainFramesOnOneArcDoesNotOutweighTheFramesBefore) {
  // As the closed loop's seed111 (README, "Frames of one arc share their offset's error"): twenty frames on one arc
  // put the camera 0.7 m left of where it is with a σ of 0.3 m, after frames on other arcs (a new arc every 4
  // frames) that see the truth with σ 3 cm. Taken as independent, the twenty outweigh the frames before them; as
  // frames of one arc sharing 0.6 of their errors (the default) they count for about one and a half
  // (20 / (1 + 19 · 0.6)): the car is pulled 0.20 m aside instead of 0.63 m.
  const TestPath path = MakePath(120.0, [](double) { return 0.0; });
  const auto one_arc = [](int frame, PathTrackingInput* input) {
    const bool wrong = frame >= 60 && frame < 80;
    input->lateral_m -= wrong ? 0.7 : 0.0;
    input->lateral_sigma_m = wrong ? 0.3 : 0.03;
    input->arc = wrong ? 1000 : frame / 4;
  };
  PathTrackingOptions independent = FastOptions();
  independent.offset.shared_correlation = 0.0;
  const DriveResult correlated = Drive(path, 8.0, 0.1, 0.0, FastOptions(), 2.7, one_arc);
  const DriveResult uncorrelated = Drive(path, 8.0, 0.1, 0.0, independent, 2.7, one_arc);
  ASSERT_TRUE(correlated.reached_end);
  ASSERT_TRUE(uncorrelated.reached_end);
  std::cout << "max deviation: frames of one arc correlated " << MaxAbsAfter(correlated, 0.0) << " m, independent "
            << MaxAbsAfter(uncorrelated, 0.0) << " m\n";
  EXPECT_LT(MaxAbsAfter(correlated, 0.0), 0.25);
  EXPECT_GT(MaxAbsAfter(uncorrelated, 0.0), 0.5);
}

// The same run with the bas-relief: the seven frames' poses rest on points 20 m ahead, where a camera 1 m left and
// turned 1/20 rad right of the truth sees them alike (heading_per_lateral −1/20 rad/m). The filtered offset
// corrects the offset but not the turn that came with it; with heading_from_offset the law steers by the heading
// that goes with the filtered offset, the truth.
TEST(PathTracker, ARunOfBasReliefFramesTurnsTheCarOnlyWithTheirOwnHeading) {
  const TestPath path = MakePath(120.0, [](double) { return 0.0; });
  const double depth = 20.0;
  const auto phantom = [&](int frame, PathTrackingInput* input) {
    const bool wrong = frame >= 60 && frame < 67;
    input->lateral_m -= wrong ? 1.0 : 0.0;
    input->heading_error_rad += wrong ? 1.0 / depth : 0.0;
    input->heading_per_lateral = -1.0 / depth;
    input->lateral_sigma_m = wrong ? 0.05 : 0.03;
  };
  PathTrackingOptions conditioned = FastOptions();
  conditioned.heading_from_offset = true;
  const DriveResult with_heading = Drive(path, 8.0, 0.1, 0.0, conditioned, 2.7, phantom);
  ASSERT_TRUE(with_heading.reached_end);
  EXPECT_LT(MaxAbsAfter(with_heading, 0.0), 0.05);
  const DriveResult own_heading = Drive(path, 8.0, 0.1, 0.0, FastOptions(), 2.7, phantom);
  ASSERT_TRUE(own_heading.reached_end);
  EXPECT_GT(MaxAbsAfter(own_heading, 0.0), 0.15);
}

// A frame whose pose rests on a few features (σ of its heading 0.12 rad) gives a heading 0.1 rad off, as the closed
// loop's rate5 at 5 Hz (README, "The heading carried by the motion"). Every other frame is right within its σ of 6
// mrad. On a straight and in a left turn of radius 25 m, at 8 m/s and 5 Hz (1.6 m per frame): with the heading carried
// by the motion (the default) the car hardly answers the bad frame; steered by each frame's own heading it swerves.
TEST(PathTracker, AHeadingWithALargeSigmaDoesNotSwerveTheCar) {
  for (const double radius : {0.0, 25.0}) {
    const auto kappa = [radius](double s) { return radius > 0 && s > 40.0 && s < 100.0 ? 1.0 / radius : 0.0; };
    const TestPath path = MakePath(140.0, kappa);
    const int bad_frame = 40;  // 64 m: in the turn when there is one
    const auto one_bad = [&](int frame, PathTrackingInput* input) {
      input->lateral_sigma_m = 0.03;
      input->heading_sigma_rad = frame == bad_frame ? 0.12 : 0.006;
      input->heading_error_rad += frame == bad_frame ? -0.1 : 0.0;
      input->path_curvature = kappa(1.6 * frame);  // the camera's metres driven, near enough to the path's
    };
    PathTrackingOptions own = FastOptions();
    own.heading_process_sigma = 0.0;
    const DriveResult carried = Drive(path, 8.0, 0.2, 0.0, FastOptions(), 2.7, one_bad);
    const DriveResult each_own = Drive(path, 8.0, 0.2, 0.0, own, 2.7, one_bad);
    ASSERT_TRUE(carried.reached_end);
    ASSERT_TRUE(each_own.reached_end);
    const auto max_after_bad_frame = [&](const DriveResult& drive) {
      double worst = 0.0;
      for (size_t i = bad_frame; i < std::min<size_t>(drive.lateral.size(), bad_frame + 15); ++i) {
        worst = std::max(worst, std::abs(drive.lateral[i]));
      }
      return worst;
    };
    std::cout << "radius " << radius << " m: largest offset after the bad frame, heading carried "
              << max_after_bad_frame(carried) << " m, each frame's own " << max_after_bad_frame(each_own) << " m\n";
    EXPECT_LT(max_after_bad_frame(carried), 0.05) << radius;
    EXPECT_GT(max_after_bad_frame(each_own), 0.15) << radius;
  }
}

// Where every heading is well measured, the carried one changes nothing that matters: from 1.5 m beside on a straight
// and through the S-bend the car drives as when steered by each frame's own heading.
TEST(PathTracker, WellMeasuredHeadingsAreTakenAsTheyAre) {
  const auto s_bend = [](double s) { return std::sin(2 * M_PI * s / 40.0) / 25.0; };
  for (const bool bend : {false, true}) {
    const TestPath path = bend ? MakePath(160.0, s_bend) : MakePath(80.0, [](double) { return 0.0; });
    const auto measured = [&](int frame, PathTrackingInput* input) {
      input->lateral_sigma_m = 0.03;
      input->heading_sigma_rad = 0.006;
      input->heading_error_rad += frame % 2 ? 0.004 : -0.004;
      input->path_curvature = bend ? s_bend(0.8 * frame) : 0.0;
    };
    PathTrackingOptions own = FastOptions();
    own.heading_process_sigma = 0.0;
    const double start = bend ? 0.0 : 1.5;
    const DriveResult carried = Drive(path, 8.0, 0.1, start, FastOptions(), 2.7, measured);
    const DriveResult each_own = Drive(path, 8.0, 0.1, start, own, 2.7, measured);
    ASSERT_TRUE(carried.reached_end);
    ASSERT_TRUE(each_own.reached_end);
    EXPECT_LT(MaxAbsAfter(carried, 15.0), bend ? 0.10 : 0.2) << bend;
    EXPECT_NEAR(MaxAbsAfter(carried, 15.0), MaxAbsAfter(each_own, 15.0), 0.02) << bend;
  }
}

TEST(PathTracker, FilteredOffsetFollowsTheCarOntoThePath) {
  // From 1.5 m beside, the offset closes over ~10 m: carried by the commanded motion, the frames of the window agree
  // with the current one, and the car converges as with each frame's own offset.
  const TestPath path = MakePath(80.0, [](double) { return 0.0; });
  const auto noisy = [](int frame, PathTrackingInput* input) {
    input->lateral_m += (frame % 2 ? 0.03 : -0.03);
    input->lateral_sigma_m = 0.03;
  };
  PathTrackingOptions own = FastOptions();
  own.offset.process_sigma = 0.0;
  const DriveResult with_filter = Drive(path, 8.0, 0.1, 1.5, FastOptions(), 2.7, noisy);
  const DriveResult without = Drive(path, 8.0, 0.1, 1.5, own, 2.7, noisy);
  EXPECT_LT(MaxAbsAfter(with_filter, 15.0), 0.1);
  EXPECT_LT(MaxAbsAfter(with_filter, 15.0), MaxAbsAfter(without, 15.0) + 0.02);
  // No overshoot to the other side beyond what each frame's own offset gives.
  double lowest_with = 0.0, lowest_without = 0.0;
  for (double l : with_filter.lateral) lowest_with = std::min(lowest_with, l);
  for (double l : without.lateral) lowest_without = std::min(lowest_without, l);
  EXPECT_GT(lowest_with, lowest_without - 0.05);
}

TEST(PathTracker, FramesWithoutMotionKeepTheOffsetWindowBounded) {
  // Frames that add no distance (dt 0: the same instant delivered again) stay in the window until 64 newer ones
  // push them out, so thousands of them neither slow the law down nor outvote what it sees now for long.
  PathTracker tracker(FastOptions());
  PathTrackingInput input = ConfidentFrame();
  input.dt = 0.0;
  input.lateral_m = 0.4;
  input.lateral_sigma_m = 0.03;
  for (int i = 0; i < 3000; ++i) tracker.Update(input);
  input.lateral_m = -0.4;  // left of the path now
  PathTrackingCommand command;
  for (int i = 0; i < 40; ++i) command = tracker.Update(input);
  EXPECT_LT(command.curvature, 0.0);  // the newer frames are the majority of the 64: steer right, back to the path
}

TEST(PathTracker, StraightPathConvergesFromAnOffset) {
  const TestPath path = MakePath(80.0, [](double) { return 0.0; });
  for (double speed : {2.0, 8.0}) {
    const DriveResult drive = Drive(path, speed, 0.1, 1.5, FastOptions());
    ASSERT_TRUE(drive.reached_end);
    // Within 0.2 m after at most 15 m, within 2 cm later on, no overshoot beyond 0.2 m.
    EXPECT_LT(MaxAbsAfter(drive, 15.0), 0.2) << speed << " m/s";
    EXPECT_LT(MaxAbsAfter(drive, 40.0), 0.02) << speed << " m/s";
    double most_left = 0.0;
    for (double e : drive.lateral) most_left = std::min(most_left, e);
    EXPECT_GT(most_left, -0.2) << "overshoot at " << speed << " m/s";
  }
}

TEST(PathTracker, ConstantCurvatureTurnHasNoSteadyOffset) {
  // A 20 m straight, then a left turn of radius 7 m (the simulated town's corners) through 360 degrees.
  const double radius = 7.0;
  const double turn_end = 20.0 + 2 * M_PI * radius;
  const TestPath path = MakePath(turn_end + 20.0, [&](double s) { return s > 20.0 && s < turn_end ? 1.0 / radius : 0.0; });
  PathTrackingOptions options = FastOptions();
  const DriveResult drive = Drive(path, 3.0, 0.1, 0.0, options);
  ASSERT_TRUE(drive.reached_end);
  // The entry and exit of the turn (curvature steps) cost a few centimetres; once the entry has died out (it decays
  // like exp(-s / D)), nothing is left in the turn.
  EXPECT_LT(MaxAbsAfter(drive, 0.0), 0.10);
  double late_turn = 0.0;
  for (size_t i = 0; i < drive.lateral.size(); ++i) {
    if (drive.driven[i] > turn_end - 10.0 && drive.driven[i] < turn_end - 1.0) {
      late_turn = std::max(late_turn, std::abs(drive.lateral[i]));
    }
  }
  EXPECT_LT(late_turn, 0.005);
}

TEST(PathTracker, SBendAtSpeedStaysWithinTenCentimetres) {
  // Curvature varying smoothly left and right (period 40 m, radius 25 m at the peaks), at 8 m/s.
  const TestPath path = MakePath(160.0, [](double s) { return std::sin(2 * M_PI * s / 40.0) / 25.0; });
  const DriveResult drive = Drive(path, 8.0, 0.1, 0.0, FastOptions());
  ASSERT_TRUE(drive.reached_end);
  EXPECT_LT(MaxAbsAfter(drive, 0.0), 0.10);
}

TEST(PathTracker, StopsAtOnceWhenLostAndRampsUpWhenTrackingAgain) {
  PathTrackingOptions options;
  options.max_speed = 6.0;
  options.max_acceleration = 2.0;
  PathTracker tracker(options);
  PathTrackingInput input = ConfidentFrame();
  double speed = 0.0;
  for (int i = 0; i < 50; ++i) speed = tracker.Update(input).speed;
  EXPECT_DOUBLE_EQ(speed, 6.0);
  input.tracking = false;
  const PathTrackingCommand lost = tracker.Update(input);
  EXPECT_EQ(lost.mode, SteeringMode::kStop);
  EXPECT_EQ(lost.speed, 0.0);
  input.tracking = true;
  EXPECT_NEAR(tracker.Update(input).speed, 0.2, 1e-12);  // 2 m/s² for 0.1 s
  // Unsure (confidence below `confident`) or without a metric offset: slower.
  for (int i = 0; i < 50; ++i) speed = tracker.Update(input).speed;
  input.confidence = 0.9;
  EXPECT_DOUBLE_EQ(tracker.Update(input).speed, 3.0);
  input.confidence = 1.0;
  input.metric = false;
  input.image_steering_valid = true;
  input.image_steering = 0.2;
  const PathTrackingCommand image = tracker.Update(input);
  EXPECT_EQ(image.mode, SteeringMode::kImage);
  EXPECT_DOUBLE_EQ(image.speed, 3.0);
  EXPECT_TRUE(std::isnan(image.lateral_m));  // no metric offset steered by
  EXPECT_TRUE(std::isnan(image.heading_error_rad));
  EXPECT_TRUE(std::isnan(lost.lateral_m));
}

TEST(PathTracker, SlowsDownForTheCurvatureAheadAndLimitsTheCommand) {
  PathTrackingOptions options;
  options.max_speed = 8.0;
  options.max_acceleration = 100.0;
  options.max_curvature = 0.2;
  options.max_curvature_rate = 1.0;
  PathTracker tracker(options);
  PathTrackingInput input = ConfidentFrame();
  input.curvature_ahead = 1.0 / 6.0;
  input.lateral_m = 5.0;  // far right: the law wants a sharp left turn
  const PathTrackingCommand first = tracker.Update(input);
  EXPECT_NEAR(first.speed, std::sqrt(1.5 * 6.0), 1e-9);
  EXPECT_NEAR(first.curvature, 0.1, 1e-12);  // rate limit: 1 /m/s for 0.1 s
  PathTrackingCommand later;
  for (int i = 0; i < 10; ++i) later = tracker.Update(input);
  EXPECT_NEAR(later.curvature, 0.2, 1e-12);  // value limit
}

TEST(PathTrackingOptions, RejectsImplausibleValues) {
  PathTrackingOptions options;
  EXPECT_TRUE(options.Check());
  options.camera_forward = 0.0;
  std::string error;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("camera_forward"), std::string::npos);
  EXPECT_THROW(PathTracker{options}, std::invalid_argument);
  options = PathTrackingOptions();
  options.offset.outlier_probability = 1.0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("outlier_probability"), std::string::npos);
  options = PathTrackingOptions();
  options.offset.min_sigma = 0.0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("min_sigma"), std::string::npos);
}

}  // namespace
}  // namespace retrace
