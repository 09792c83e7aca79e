// Closed-loop teach and repeat in the simulator. A map is taught on the default town drive (200 frames, three
// turns); the car then starts where the repeat variant starts (1 m to the side of the teach drive, another sun,
// pedestrians and cars elsewhere) and is driven by retrace alone: by the camera-point law on the metric offset from
// the taught path (control/path_tracking.h; the localizer knows the camera's height), or by Segvic 2009 eq. (10).
// Ground truth: the distance of the camera from the taught camera path.

#include "retrace/drive/closed_loop.h"

#include <iostream>

#include <gtest/gtest.h>

#include "retrace/sim/recording.h"
#include "retrace/teach/teacher.h"

namespace retrace {
namespace {

TEST(DistanceToPath, MeasuresOnTheGroundPlaneAlongThePolyline) {
  std::vector<TimedPose> path(3);
  path[1].world_from_cam.translation = Vector3d(0, 0, 10);
  path[2].world_from_cam.translation = Vector3d(10, 0, 10);
  double along = -1;
  // Beside the first segment, 2 m to the right and 1.5 m higher (height does not count).
  EXPECT_NEAR(DistanceToPath(Vector3d(2, -1.5, 4), path, &along), 2.0, 1e-12);
  EXPECT_NEAR(along, 0.4, 1e-12);
  // Past the corner, nearest to the second segment.
  EXPECT_NEAR(DistanceToPath(Vector3d(5, 0, 13), path, &along), 3.0, 1e-12);
  EXPECT_NEAR(along, 1.5, 1e-12);
  // 0.6 m past the end, 0.05 m to its right (-z of a path travelling along +x): the deviation is the 0.05 m beside
  // the end stretch's line, not the 0.6 m of overshoot; likewise 0.5 m short of the start, 0.03 m to the right.
  EXPECT_NEAR(DistanceToPath(Vector3d(10.6, 0, 9.95), path, &along), 0.05, 1e-12);
  EXPECT_NEAR(along, 2.0, 1e-12);
  EXPECT_NEAR(DistanceToPath(Vector3d(0.03, 0, -0.5), path, &along), 0.03, 1e-12);
  EXPECT_NEAR(along, 0.0, 1e-12);
  // At the corner (an interior vertex) the distance stands: outside the turn it is the distance to the vertex.
  EXPECT_NEAR(DistanceToPath(Vector3d(-1, 0, 11), path, &along), std::sqrt(2.0), 1e-12);
}

TEST(ClosedLoopOptions, CheckRejectsBadValues) {
  ClosedLoopOptions options;
  EXPECT_TRUE(options.Check());
  options.tracking.max_speed = 0;
  EXPECT_FALSE(options.Check());
  options = ClosedLoopOptions();
  options.frame_period = -0.1;
  EXPECT_FALSE(options.Check());
}

struct DriveSpec {
  ClosedLoopControl control = ClosedLoopControl::kPath;
  double image_gain = PathTrackingOptions().image_gain;
  bool with_taught_path = true;
  double lateral_offset = 1.0;  // the repeat drive's start, metres right of the teach drive
  int blackout_start = 0, blackout_frames = 0;
};

class ClosedLoop : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    scenario_.num_frames = 200;
    RecordedDrive teach = RecordDrive(ApplyVariant(scenario_, ScenarioVariant::kTeach));
    Teacher teacher(*teach.camera, TeachOptions(), nullptr);
    for (const Frame& frame : teach.frames) teacher.AddFrame(frame);
    teacher.Finish();
    map_ = new Map(teacher.map());
    taught_ = new std::vector<TimedPose>(teach.truth);
  }
  static void TearDownTestSuite() {
    delete map_;
    delete taught_;
  }

  // Drives the repeat variant; `steps` (optional) receives (state tracking, speed command) per frame.
  static ClosedLoopSummary Drive(const DriveSpec& spec, std::vector<std::pair<bool, double>>* steps = nullptr) {
    Scenario scenario = scenario_;
    scenario.repeat.lateral_offset = spec.lateral_offset;
    Simulator simulator(ApplyVariant(scenario, ScenarioVariant::kRepeat));
    LocalizerOptions localizer_options;
    localizer_options.path.camera_height = scenario.vehicle.camera_height;  // what the robot's owner measures
    Localizer localizer(*map_, simulator.camera(), localizer_options);
    ClosedLoopOptions options;
    options.control = spec.control;
    options.tracking.camera_forward = scenario.vehicle.camera_forward;
    options.tracking.image_gain = spec.image_gain;
    options.blackout_start = spec.blackout_start;
    options.blackout_frames = spec.blackout_frames;
    options.max_frames = 400;
    options.max_stopped_frames = 10;  // a car that lost the map for good gives up soon
    const ClosedLoopSummary run = DriveClosedLoop(
        &simulator, &localizer, *map_, spec.with_taught_path ? *taught_ : std::vector<TimedPose>(), options,
        [&](const ClosedLoopStep& step) {
          if (steps != nullptr) steps->emplace_back(step.result->state == LocalizerState::kTracking, step.command.speed);
        });
    const PathTrackingFigures figures = run.Figures(10.0);
    std::cout << "closed loop, " << (spec.control == ClosedLoopControl::kPath ? "path law" : "eq. (10)") << ", gain "
              << spec.image_gain << ", start " << spec.lateral_offset << " m: " << run.frames << " frames, "
              << run.tracking << " tracking, " << run.path_frames << " by the metric path; after 10 m RMS "
              << figures.rms << " m, p95 " << figures.p95 << " m, max " << figures.max << " m"
              << (run.reached_end ? ", reached the end" : "") << (run.left_path ? ", left the path" : "") << "\n";
    return run;
  }

  static Scenario scenario_;
  static Map* map_;
  static std::vector<TimedPose>* taught_;
};

Scenario ClosedLoop::scenario_;
Map* ClosedLoop::map_ = nullptr;
std::vector<TimedPose>* ClosedLoop::taught_ = nullptr;

TEST_F(ClosedLoop, PathLawStaysWithinTenCentimetresAndBeatsEquationTen) {
  const ClosedLoopSummary path = Drive({});
  EXPECT_TRUE(path.reached_end);
  EXPECT_EQ(path.tracking, path.frames);
  EXPECT_GT(path.path_frames, path.frames * 9 / 10);
  const PathTrackingFigures figures = path.Figures(10.0);
  ASSERT_GT(figures.frames, 100);
  EXPECT_LE(figures.rms, 0.10);
  EXPECT_LE(figures.max, 0.30);
  // Side by side, the same drive steered by eq. (10).
  DriveSpec eq10;
  eq10.control = ClosedLoopControl::kImage;
  const ClosedLoopSummary image = Drive(eq10);
  EXPECT_TRUE(image.reached_end);
  EXPECT_EQ(image.path_frames, 0);
  EXPECT_GT(image.Figures(10.0).rms, 2 * figures.rms);
}

TEST_F(ClosedLoop, StartingBesideThePathConverges) {
  // 1.5 m to the right at the start: within 0.2 m after at most 15 m driven, and staying there.
  DriveSpec spec;
  spec.lateral_offset = 1.5;
  const ClosedLoopSummary run = Drive(spec);
  EXPECT_TRUE(run.reached_end);
  ASSERT_FALSE(run.deviations.empty());
  EXPECT_GT(run.deviations.front(), 1.0);
  EXPECT_LE(run.Figures(15.0).max, 0.2);
}

TEST_F(ClosedLoop, TooWeakImageSteeringLeavesThePathInTheTurns) {
  // eq. (10) with half its gain turns too late: the car runs wide in a turn and the localizer loses the map there.
  // The checks above are therefore not ones any command would pass.
  DriveSpec spec;
  spec.control = ClosedLoopControl::kImage;
  spec.image_gain = 0.5 * PathTrackingOptions().image_gain;
  const ClosedLoopSummary run = Drive(spec);
  EXPECT_FALSE(run.reached_end);
  EXPECT_LT(run.tracking, run.frames);
}

TEST_F(ClosedLoop, StopsWhenLostAndResumesWhenLocalizedAgain) {
  // The lens is covered for 5 frames in the middle of the drive.
  DriveSpec spec;
  spec.blackout_start = 60;
  spec.blackout_frames = 5;
  std::vector<std::pair<bool, double>> steps;
  const ClosedLoopSummary run = Drive(spec, &steps);
  ASSERT_GT(steps.size(), 70u);
  int lost_frames = 0;
  for (const auto& [tracking, speed] : steps) {
    if (!tracking) {
      ++lost_frames;
      EXPECT_EQ(speed, 0.0);  // the command is 0 in the very frame the localizer is not tracking
    }
  }
  EXPECT_GE(lost_frames, 1);
  EXPECT_GE(run.stopped_frames, lost_frames);
  EXPECT_GT(steps[59].second, 0.0);  // driving before the blackout ...
  EXPECT_TRUE(run.reached_end);      // ... and on to the end after it
  EXPECT_LE(run.Figures(10.0).max, 0.30);
}

TEST_F(ClosedLoop, WithoutGroundTruthTheDriveEndsAtTheMapsLastArc) {
  // What a robot knows: the drive stops once the localizer places the car past the end of the map's last arc.
  DriveSpec spec;
  spec.with_taught_path = false;
  const ClosedLoopSummary run = Drive(spec);
  EXPECT_TRUE(run.reached_end);
  EXPECT_TRUE(run.deviations.empty());
  EXPECT_GT(run.frames, 200);  // from rest, slower in the turns than the teach drive's 200 frames
  EXPECT_LT(run.frames, 320);
}

}  // namespace
}  // namespace retrace
