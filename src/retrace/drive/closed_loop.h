#pragma once

// Closed-loop teach and repeat in the simulator: the simulated car is steered by the repeat's command alone
// (Segvic 2009, eq. (10)), frame by frame, as a robot would be. Every frame the simulator renders what the camera
// sees, the Localizer places it in the taught map and returns w, and the front wheels are set to -gain * w (w > 0
// means the features sit right of where the next key-image saw them; the simulator's steering is positive to the
// left) for one frame period at a constant speed.
//
// Ground truth comes from the simulator: with the taught drive's camera poses, each frame is scored by its distance
// from the taught camera path on the ground plane.

#include <functional>
#include <limits>
#include <vector>

#include "retrace/dataset/ground_truth.h"
#include "retrace/repeat/localizer.h"
#include "retrace/sim/simulator.h"

namespace retrace {

struct ClosedLoopOptions {
  // Constant speed of the car (m/s). The built-in scenario teaches at up to 8 m/s and slows in its turns.
  double speed = 6.0;
  // Time between frames (seconds): the car drives this long with one steering command.
  double frame_period = 0.1;
  // The front wheels are set to -steering_gain * w; the gain k of eq. (10) is the Localizer's own.
  double steering_gain = 1.0;
  // The drive stops after this many frames ...
  int max_frames = 2000;
  // ... or when the car is farther than this (metres) from the taught path (needs the taught poses).
  double max_deviation = 5.0;

  bool Check(std::string* error = nullptr) const;
};

// One frame of a closed-loop drive.
struct ClosedLoopStep {
  const SimFrame* view = nullptr;    // what the camera saw and where it was (ground truth)
  const FrameResult* result = nullptr;
  double wheels = 0.0;               // steering applied after this frame (radians, positive left)
  // Distance (metres) on the ground plane from the taught camera path and the position along it (taught frames,
  // fractional); NaN without taught poses.
  double deviation = std::numeric_limits<double>::quiet_NaN();
  double along = std::numeric_limits<double>::quiet_NaN();
};

struct ClosedLoopSummary {
  int frames = 0;
  int tracking = 0;          // frames in state kTracking
  bool reached_end = false;  // past the end of the taught route
  bool left_path = false;    // stopped farther than max_deviation from the taught path
  bool left_route = false;   // stopped where the simulated world ends (Simulator::OffRoute: past the scenario
                             // route's end or far off it), e.g. lost without taught poses to measure the deviation
  std::vector<double> deviations;  // per frame, when taught poses were given

  double MedianDeviation() const;
  double MaxDeviation() const;
};

// Distance on the ground plane (world x, z; y points down) from `position` to the polyline through the camera
// centres of `taught`, and where along it (taught frame index, fractional) the nearest point lies.
double DistanceToPath(const Vector3d& position, const std::vector<TimedPose>& taught, double* along);

// Drives `simulator` (placed at its scenario's start) with `localizer`'s steering until the car is past the end of
// the taught route (the last taught pose, or the end of the map's last arc without taught poses), leaves the taught
// path, leaves the simulated route (Simulator::OffRoute), or `max_frames` have gone by. `on_step` (optional) sees
// every frame.
ClosedLoopSummary DriveClosedLoop(Simulator* simulator, Localizer* localizer, const Map& map,
                                  const std::vector<TimedPose>& taught, const ClosedLoopOptions& options,
                                  const std::function<void(const ClosedLoopStep&)>& on_step = {});

}  // namespace retrace
