// Closed-loop teach and repeat in the simulator: the car is steered by retrace's own command (Segvic 2009, eq. (10))
// and nothing else. A map is taught on the default town drive (200 frames, three turns); the car then starts where
// the repeat variant starts (1 m to the side of the teach drive, another sun, pedestrians and cars elsewhere) and
// drives at a constant 6 m/s, one frame every 0.1 s, with the front wheels at -w (w > 0 turns right in image
// terms; the simulator's steering is positive to the left). Ground truth: the distance of the camera from the
// taught camera path on the ground plane.

#include <algorithm>
#include <cmath>
#include <iostream>
#include <vector>

#include <gtest/gtest.h>

#include "retrace/repeat/localizer.h"
#include "retrace/sim/recording.h"
#include "retrace/sim/simulator.h"
#include "retrace/teach/teacher.h"

namespace retrace {
namespace {

// Distance on the ground plane (world x, z; y is down) from `position` to the polyline of the taught camera centres,
// and how far along it (in taught frames, fractional) the nearest point lies.
double DistanceToTaughtPath(const Vector3d& position, const std::vector<TimedPose>& taught, double* along) {
  const Vector2d p(position.x(), position.z());
  double best = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i + 1 < taught.size(); ++i) {
    const Vector3d& a3 = taught[i].world_from_cam.translation;
    const Vector3d& b3 = taught[i + 1].world_from_cam.translation;
    const Vector2d a(a3.x(), a3.z()), ab = Vector2d(b3.x(), b3.z()) - a;
    const double t = ab.squaredNorm() > 0 ? std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
    const double d = (a + t * ab - p).norm();
    if (d < best) {
      best = d;
      *along = static_cast<double>(i) + t;
    }
  }
  return best;
}

struct ClosedLoopRun {
  int frames = 0;
  int tracking = 0;
  bool reached_end = false;
  std::vector<double> deviations;  // metres, per frame

  double Median() const {
    std::vector<double> d = deviations;
    std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
    return d[d.size() / 2];
  }
  double Max() const { return *std::max_element(deviations.begin(), deviations.end()); }
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

  // Drives the repeat variant with the front wheels at -gain * w until the car passes the taught path's end, leaves
  // it by more than 5 m, or 400 frames have gone by.
  static ClosedLoopRun Drive(double gain) {
    Simulator simulator(ApplyVariant(scenario_, ScenarioVariant::kRepeat));
    Localizer localizer(*map_, simulator.camera());
    ClosedLoopRun run;
    SimFrame view = simulator.Step(0.0, kSpeed, 0.0);
    for (int i = 0; i < 400; ++i) {
      Frame frame;
      frame.index = frame.source_index = static_cast<size_t>(i);
      frame.timestamp = view.timestamp;
      frame.image = view.image;
      const FrameResult result = localizer.ProcessFrame(frame);
      double along = 0.0;
      run.deviations.push_back(DistanceToTaughtPath(view.world_from_cam.translation, *taught_, &along));
      ++run.frames;
      run.tracking += result.state == LocalizerState::kTracking;
      if (along >= static_cast<double>(taught_->size()) - 1.5) {
        run.reached_end = true;
        break;
      }
      if (run.deviations.back() > 5.0) break;
      const double wheels = result.steering_valid ? -gain * result.steering : 0.0;
      view = simulator.Step(wheels, kSpeed, 0.1);
    }
    std::cout << "closed loop, gain " << gain << ": " << run.frames << " frames, " << run.tracking
              << " tracking, distance from the taught path median " << run.Median() << " m, max " << run.Max()
              << " m, first " << run.deviations.front() << " m" << (run.reached_end ? ", reached the end" : "")
              << "\n";
    return run;
  }

  static constexpr double kSpeed = 6.0;  // m/s; the teach drive went up to 8 m/s and slowed for its turns
  static Scenario scenario_;
  static Map* map_;
  static std::vector<TimedPose>* taught_;
};

Scenario ClosedLoop::scenario_;
Map* ClosedLoop::map_ = nullptr;
std::vector<TimedPose>* ClosedLoop::taught_ = nullptr;

TEST_F(ClosedLoop, SteeringByEquationTenFollowsTheTaughtPath) {
  const ClosedLoopRun run = Drive(LocalizerOptions().steering_gain);
  // Measured: 213 frames all tracking, 0.80 m off at the start, median 0.22 m, max 0.92 m (in a turn).
  EXPECT_TRUE(run.reached_end);
  EXPECT_EQ(run.tracking, run.frames);
  EXPECT_GT(run.deviations.front(), 0.5);  // it starts beside the taught path ...
  EXPECT_LT(run.Median(), 0.4);            // ... and converges onto it
  EXPECT_LT(run.Max(), 1.5);
}

TEST_F(ClosedLoop, TooWeakSteeringLeavesThePathInTheTurns) {
  // Half the gain turns too late: the car runs wide in a turn (5.2 m off after 127 frames) and the localizer loses
  // the map there. The check above is therefore not one any command would pass.
  const ClosedLoopRun run = Drive(0.5 * LocalizerOptions().steering_gain);
  EXPECT_GT(run.Max(), 3.0);
  EXPECT_LT(run.tracking, run.frames);
}

}  // namespace
}  // namespace retrace
