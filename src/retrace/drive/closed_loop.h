#pragma once

// Closed-loop teach and repeat in the simulator: the simulated car is steered by retrace alone, frame by frame, as a
// robot would be. Every frame the simulator renders what the camera sees, the Localizer places it in the taught map,
// and the path tracker (control/path_tracking.h) turns its result into a curvature and a speed: by default the
// camera-point law on the metric offset from the taught path (FrameResult::path; the Localizer needs the camera's
// height), else — and with `control = kImage` always — Segvic 2009 eq. (10) on the image (w > 0 means the features
// sit right of where the next key-image saw them: turn right). The front wheels are set to atan(L κ) (L the
// scenario's wheelbase; the simulator's steering is positive to the left) for one frame period. The car stops when
// the localizer is not tracking and drives on when it tracks again.
//
// Ground truth comes from the simulator: with the taught drive's camera poses, each frame is scored by its distance
// from the taught camera path on the ground plane.

#include <functional>
#include <limits>
#include <vector>

#include "retrace/control/path_tracking.h"
#include "retrace/dataset/ground_truth.h"
#include "retrace/repeat/evaluation.h"
#include "retrace/repeat/localizer.h"
#include "retrace/sim/simulator.h"

namespace retrace {

enum class ClosedLoopControl { kPath, kImage };

struct ClosedLoopOptions {
  // Steering law: the camera-point law on the metric offset (falling back to eq. (10) where there is none), or
  // eq. (10) alone, for comparison.
  ClosedLoopControl control = ClosedLoopControl::kPath;
  // Time between frames (seconds): the car drives this long with one command.
  double frame_period = 0.1;
  // The path tracker: its max_speed is the car's top speed (it slows down in turns and when unsure, and stops when
  // lost; the built-in scenario teaches at up to 8 m/s), its camera_forward should be the vehicle's.
  PathTrackingOptions tracking;
  // A covered lens: frames [blackout_start, blackout_start + blackout_frames) are replaced by a black image (the
  // car must stop and resume; 0 frames = none).
  int blackout_start = 0;
  int blackout_frames = 0;
  // The drive gives up after this many frames in a row standing still.
  int max_stopped_frames = 50;
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
  PathTrackingCommand command;       // the path tracker's command after this frame
  // The true lateral offset (positive right) and heading error against the taught path; NaN without taught poses.
  double true_lateral = std::numeric_limits<double>::quiet_NaN();
  double true_heading_error = std::numeric_limits<double>::quiet_NaN();
  // Deviation (metres) on the ground plane from the taught camera path (DeviationFromPath) and the position along it
  // (taught frames, fractional); NaN without taught poses.
  double deviation = std::numeric_limits<double>::quiet_NaN();
  double along = std::numeric_limits<double>::quiet_NaN();
};

// Path-tracking figures of a drive: the camera's distance from the taught path over the frames after the first
// `skip_m` metres driven.
struct PathTrackingFigures {
  int frames = 0;
  double rms = std::numeric_limits<double>::quiet_NaN();
  double p95 = std::numeric_limits<double>::quiet_NaN();
  double max = std::numeric_limits<double>::quiet_NaN();
};

struct ClosedLoopSummary {
  int frames = 0;
  int tracking = 0;          // frames in state kTracking
  bool reached_end = false;  // past the end of the taught route
  bool left_path = false;    // stopped farther than max_deviation from the taught path
  bool left_route = false;   // stopped where the simulated world ends (Simulator::OffRoute: past the scenario
                             // route's end or far off it), e.g. lost without taught poses to measure the deviation
  bool stalled = false;      // stood still for max_stopped_frames frames (lost and not relocalized)
  int stopped_frames = 0;    // frames with a zero speed command
  int path_frames = 0;       // frames steered by the metric law
  std::vector<double> deviations;  // per frame, when taught poses were given
  std::vector<double> driven;      // per frame, metres the camera has driven

  double MedianDeviation() const;
  PathTrackingFigures Figures(double skip_m) const;
  double MaxDeviation() const;
};

// Deviation of a camera from the taught path, on the ground plane (world x, z; y points down): its distance to the
// polyline through the camera centres of the `taught_poses` taught poses (TruthAgainstTaughtPath over all of them),
// except before the first or beyond the last centre, where it is the distance from the line of the end stretch —
// how far the car is short of the path's start or past its end is not a deviation (a drive stops in the frame that
// passes the end, up to a frame's travel beyond it).
double DeviationFromPath(const PathTruth& truth, size_t taught_poses);

// DeviationFromPath of a camera at `position`, and where along the path (taught frame index, fractional) the nearest
// point lies.
double DistanceToPath(const Vector3d& position, const std::vector<TimedPose>& taught, double* along);

// Drives `simulator` (placed at its scenario's start) with `localizer`'s steering until the car is past the end of
// the taught route (the last taught pose, or the end of the map's last arc without taught poses), leaves the taught
// path, leaves the simulated route (Simulator::OffRoute), or `max_frames` have gone by. `on_step` (optional) sees
// every frame.
ClosedLoopSummary DriveClosedLoop(Simulator* simulator, Localizer* localizer, const Map& map,
                                  const std::vector<TimedPose>& taught, const ClosedLoopOptions& options,
                                  const std::function<void(const ClosedLoopStep&)>& on_step = {});

}  // namespace retrace
