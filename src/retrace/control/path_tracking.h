#pragma once

// Path tracking: the steering and speed commands of a car-like robot repeating a taught path.
//
// Steering law ("camera point" law, kinematic, derived here for retrace): the camera rides `camera_forward` metres
// ahead of the vehicle's reference point (the rear axle, about which a car turns with curvature κ). When the vehicle
// drives with curvature κ, the camera moves in a direction turned atan(d κ) to the left of the vehicle's heading
// (d = camera_forward). With e the camera's lateral offset from the taught path and ψ its heading error (both
// positive to the right, repeat/taught_path.h), the camera's direction of motion relative to the path is
// φ = ψ − atan(d κ), and de/ds = sin φ. The law asks the camera to head back to the path along
//   φ* = −atan(e / D)     (D = approach_distance: an offset closes like exp(−s / D) over the distance driven s),
// which gives
//   κ = tan(ψ + atan(e / D)) / d.
// On a turn of the taught path with curvature κ_p the camera's heading is ψ = atan(d κ_p) to the right of the path
// when it follows it exactly, and the law then commands κ = κ_p: no offset in steady turns, without feed-forward,
// at any speed (the gains are per metre driven, not per second). The heading ψ has the zero dynamics
// dψ/ds ≈ −ψ / d (stable when driving forward; sampled every v·Δt metres, stable while v·Δt < 2 d).
//
// The offset e the law uses is not the frame's alone: the recent frames' offsets, carried to the current frame by the
// commanded motion (de/ds = sin φ), are combined robustly (PathTrackingOptions::offset), so that a run of frames a
// metre off does not turn the car towards a phantom path. The heading ψ is the frame's own combined with the last
// frame's carried by the commanded motion and the taught path's curvature (dψ/ds = κ_p − κ), each by its variance
// (`heading_process_sigma`): a heading resting on a few features, with a σ of several degrees, does not swerve the car.
// Optionally (`heading_from_offset`, instead) the heading is the one that goes with that combined offset through the
// pose's covariance (the bas-relief ambiguity; README: a trade over the closed-loop drives, off by default).
//
// Without a metric offset (no camera height, or no usable absolute pose in this frame) the law falls back to the
// image steering of Segvic 2009, eq. (10) (control/steering.h): κ = −image_gain · w. Curvature is limited in value
// and rate; a car takes it as the front-wheel angle atan(L κ) (wheelbase L).
//
// Speed: at most `max_speed`; in turns at most sqrt(a_lat / |κ_ahead|) (the sharpest curvature of the taught path
// ahead); scaled by `uncertain_speed_fraction` when the place belief's confidence is below `confident` or the frame
// gave no metric offset; zero at once when the localizer is not tracking (a robot must not drive blind), and ramped
// up at `max_acceleration` when it tracks again.

#include <cstdint>
#include <limits>
#include <string>

#include "retrace/util/robust_random_walk.h"

namespace retrace {

// The path law's window of recent offsets: ObservationWindowOptions' defaults, the frames on one arc sharing a part
// 0.6 of their errors — measured: the frames' own offsets from the taught path (frame_lateral_m) against the truth
// over 23 simulated drives of the validation matrix at 0-3 m beside, each error over its σ (clipped at 3), correlate
// by 0.62 between two frames on one arc (0.72 one frame apart, 0.66 two). README, "Frames of one arc share their
// offset's error".
inline ObservationWindowOptions PathOffsetWindowOptions() {
  ObservationWindowOptions options;
  options.shared_correlation = 0.6;
  return options;
}

struct PathTrackingOptions {
  // Distance of the camera ahead of the point the vehicle turns about (a car's rear axle), metres. The simulator's
  // car: 1.8 m (sim/vehicle.h). Must be > 0: a camera on the turning point cannot steer its own position.
  double camera_forward = 1.8;
  // D: distance driven over which a lateral offset closes by a factor e (m). Smaller is stiffer; it must stay well
  // above the distance driven between two frames.
  double approach_distance = 4.0;
  // Limits of the curvature command (1/m; a car with a 2.7 m wheelbase and 35° wheels: 0.26) and of its rate of
  // change (1/m per second).
  double max_curvature = 0.25;
  double max_curvature_rate = 2.0;
  // Fallback law, Segvic 2009 eq. (10): κ = −image_gain · w (1/m per unit of w; with the simulator's 2.7 m
  // wheelbase 0.37 reproduces its front wheels at −w).
  double image_gain = 0.37;
  // Speed: top speed (m/s), lateral acceleration allowed in turns (m/s²), acceleration when speeding up (m/s²).
  double max_speed = 8.0;
  double max_lateral_acceleration = 1.5;
  double max_acceleration = 2.0;
  // Below this belief confidence, or without a metric offset, the speed is scaled by `uncertain_speed_fraction`.
  double confident = 0.99;
  double uncertain_speed_fraction = 0.5;
  // The offset the law steers by (PathTracker::FilteredOffset): the frames within `offset.window` metres driven (at
  // most `offset.max_observations`), each carried to the current frame by the camera's motion since — direction
  // φ = ψ − atan(d κ) with the commanded κ, de/ds = sin φ, over the commanded speed·dt — plus a random walk of
  // `offset.process_sigma` m/√m for what that misses; each right with its own σ (at least `offset.min_sigma`) or wrong
  // with probability `offset.outlier_probability` (uniform over `offset.outlier_range` m), combined robustly
  // (util/robust_random_walk.h; the defaults there: 20 m, 64 frames, 0.05 m/√m, 2 cm, 0.1, 10 m), the frames on one
  // arc (PathTrackingInput::arc) sharing a part `offset.shared_correlation` = 0.6 of their errors. Why: a frame whose
  // pose rests on features at one depth (a far facade) may put the camera a metre off with a σ of centimetres, several
  // frames in a row (seed3 of the validation matrix: 7 frames, 5.6 m; seed6: 14); the window must hold more right
  // frames than such a run, and a run on one arc counts for less than its number. offset.process_sigma 0: each
  // frame's own offset.
  ObservationWindowOptions offset = PathOffsetWindowOptions();
  // Steer by the heading the frame's pose gives with the combined offset instead of its own: ψ + b · (e_c − e),
  // b = PathTrackingInput::heading_per_lateral. A pose resting on points at one depth Z puts the camera δe aside
  // and turned by about −δe / Z together (the bas-relief ambiguity); where the combined offset e_c corrects δe, this
  // corrects the turn that came with it.
  bool heading_from_offset = false;
  // The heading the law steers by (without heading_from_offset): the frame's own combined with the last frame's carried
  // to this one by the motion (a one-state Kalman filter, PathTracker::FilteredHeading): dψ/ds = κ_p − κ with the
  // commanded curvature κ and the taught path's κ_p (PathTrackingInput::path_curvature), plus a random walk of
  // `heading_process_sigma` rad/√m for what that misses; the frame's heading enters with its own σ
  // (PathTrackingInput::heading_sigma_rad). A frame whose pose rests on a few features gives a heading with a σ of
  // 0.05-0.1 rad and may be that far off (the closed loop's rate5: 0.095 rad off with σ 0.12 at 5 Hz, which swerved
  // the car 0.39 m aside); a frame of a well-posed pose (σ ≲ 0.01 rad) is taken almost as it is. 0.03 rad/√m: over
  // the four closed-loop drives that missed the convergence target, the carried true heading (the map's κ_p, the
  // commands) missed the next frame's by 0.002-0.013 rad/√m (robust σ) but by 0.034-0.069 rad/√m at the 95th
  // percentile (entering turns, where the map's curvature lags), whose Gaussian σ is about 0.03. 0: each frame's own
  // heading.
  double heading_process_sigma = 0.03;
  bool Check(std::string* error = nullptr) const;
};

// What the localizer says of one frame, as the law needs it.
struct PathTrackingInput {
  bool tracking = false;         // localized on an arc (state tracking)
  double confidence = 0.0;       // the belief's confidence in that arc
  bool metric = false;           // lateral_m and heading_error_rad are valid
  double lateral_m = 0.0;        // positive right of the path
  double lateral_sigma_m = 0.0;  // its standard deviation
  // The arc whose reconstruction the frame's pose is in: the offsets of frames on one arc share a part of their
  // errors (PathTrackingOptions::offset.shared_correlation); -1 unknown.
  int64_t arc = -1;
  double heading_error_rad = 0.0;  // positive looking right of the path
  double heading_sigma_rad = 0.0;  // its standard deviation (0 unknown: the heading is taken as it is)
  double path_curvature = 0.0;     // 1/m, positive left, the taught path's curvature where the camera is
  double heading_per_lateral = 0.0;  // rad/m, the pose's regression of its heading on its offset (0 unknown)
  double curvature_ahead = 0.0;  // 1/m, the sharpest of the taught path ahead (0 when unknown)
  bool image_steering_valid = false;
  double image_steering = 0.0;   // w of eq. (10)
  double dt = 0.1;               // seconds since the previous command
};

enum class SteeringMode { kStop, kPath, kImage };
const char* SteeringModeName(SteeringMode mode);

struct PathTrackingCommand {
  SteeringMode mode = SteeringMode::kStop;
  double curvature = 0.0;  // 1/m, positive turning left
  double speed = 0.0;      // m/s
  // The lateral offset and heading error the law steered by (kPath: the offset of the recent frames combined, the
  // frame's own heading error or, with heading_from_offset, the one that goes with that offset); NaN in the other
  // modes.
  double lateral_m = std::numeric_limits<double>::quiet_NaN();
  double heading_error_rad = std::numeric_limits<double>::quiet_NaN();
};

// The camera-point law alone (no limits): κ = tan(ψ + atan(e / D)) / d.
double CameraPointCurvature(double lateral_m, double heading_error_rad, const PathTrackingOptions& options);

class PathTracker {
 public:
  explicit PathTracker(const PathTrackingOptions& options = {});  // throws std::invalid_argument for bad options
  // The command after one frame. `prefer_image` steers by eq. (10) even when a metric offset is available (for
  // comparison).
  PathTrackingCommand Update(const PathTrackingInput& input, bool prefer_image = false);
  const PathTrackingOptions& options() const { return options_; }

 private:
  PathTrackingOptions options_;
  double curvature_ = 0.0;
  double speed_ = 0.0;
  // The heading combined with the last frame's carried by the motion (PathTrackingOptions::heading_process_sigma).
  double FilteredHeading(const PathTrackingInput& input, double dt);
  double heading_ = std::numeric_limits<double>::quiet_NaN();  // the last FilteredHeading (NaN: none yet)
  double heading_variance_ = 0.0;
  double path_curvature_ = 0.0;  // the last frame's PathTrackingInput::path_curvature
  // The recent frames' offsets for FilteredOffset, each less the motion's drift up to it, at the metres driven; the
  // camera's heading over the last step is `heading`.
  double FilteredOffset(const PathTrackingInput& input, double heading, double dt);
  ObservationWindow offsets_;
  double distance_ = 0.0;
  double drift_ = 0.0;  // ∫ sin φ ds
  double steered_heading_ = std::numeric_limits<double>::quiet_NaN();  // the last frame's, with heading_from_offset
};

}  // namespace retrace
