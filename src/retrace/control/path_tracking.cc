#include "retrace/control/path_tracking.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include <fmt/format.h>

#include "retrace/util/robust_random_walk.h"

namespace retrace {

const char* SteeringModeName(SteeringMode mode) {
  switch (mode) {
    case SteeringMode::kStop:
      return "stop";
    case SteeringMode::kPath:
      return "path";
    case SteeringMode::kImage:
      return "image";
  }
  return "unknown";
}

bool PathTrackingOptions::Check(std::string* error) const {
  const auto fail = [error](const std::string& message) {
    if (error != nullptr) *error = message;
    return false;
  };
  if (!(camera_forward > 0 && camera_forward <= 20)) {
    return fail(fmt::format("camera_forward must be in (0, 20] m, got {}", camera_forward));
  }
  if (!(approach_distance > 0 && approach_distance <= 1000)) {
    return fail(fmt::format("approach_distance must be in (0, 1000] m, got {}", approach_distance));
  }
  if (!(max_curvature > 0 && max_curvature <= 10)) {
    return fail(fmt::format("max_curvature must be in (0, 10] 1/m, got {}", max_curvature));
  }
  if (!(max_curvature_rate > 0)) return fail(fmt::format("max_curvature_rate must be > 0, got {}", max_curvature_rate));
  if (!(std::abs(image_gain) <= 100)) return fail(fmt::format("image_gain must be in [-100, 100], got {}", image_gain));
  if (!(max_speed > 0 && max_speed <= 50)) return fail(fmt::format("max_speed must be in (0, 50] m/s, got {}", max_speed));
  if (!(max_lateral_acceleration > 0)) {
    return fail(fmt::format("max_lateral_acceleration must be > 0, got {}", max_lateral_acceleration));
  }
  if (!(max_acceleration > 0)) return fail(fmt::format("max_acceleration must be > 0, got {}", max_acceleration));
  if (!(confident >= 0 && confident <= 1)) return fail(fmt::format("confident must be in [0, 1], got {}", confident));
  if (!(uncertain_speed_fraction > 0 && uncertain_speed_fraction <= 1)) {
    return fail(fmt::format("uncertain_speed_fraction must be in (0, 1], got {}", uncertain_speed_fraction));
  }
  if (!(heading_process_sigma >= 0 && heading_process_sigma <= 10)) {
    return fail(fmt::format("heading_process_sigma must be in [0, 10] rad/sqrt(m), got {}", heading_process_sigma));
  }
  std::string offset_error;
  if (!offset.Check(&offset_error)) return fail("offset: " + offset_error);
  return true;
}

double CameraPointCurvature(double lateral_m, double heading_error_rad, const PathTrackingOptions& options) {
  // The camera's wanted direction of motion against its heading; kept short of ±90 degrees.
  const double limit = 0.5 * M_PI - 1e-3;
  const double turn = std::clamp(heading_error_rad + std::atan(lateral_m / options.approach_distance), -limit, limit);
  return std::tan(turn) / options.camera_forward;
}

PathTracker::PathTracker(const PathTrackingOptions& options) : options_(options) {
  std::string error;
  if (!options_.Check(&error)) throw std::invalid_argument("PathTrackingOptions: " + error);
  offsets_ = ObservationWindow(options_.offset);
}

double PathTracker::FilteredHeading(const PathTrackingInput& input, double dt) {
  const double measured = input.heading_error_rad;
  const double sigma = input.heading_sigma_rad;
  const bool known = std::isfinite(sigma) && sigma > 0.0;
  if (!std::isfinite(heading_) || !known) {
    // The first heading, or one without a σ: taken as it is.
    heading_ = measured;
    heading_variance_ = known ? sigma * sigma : 0.0;
  } else {
    // Predict: over the speed·dt metres since the last frame the path turned by κ_p (the mean of both frames') and
    // the car by the commanded κ: dψ/ds = κ_p − κ.
    const double travelled = speed_ * dt;
    const double path_curvature = 0.5 * (path_curvature_ + input.path_curvature);
    const double predicted = heading_ + (path_curvature - curvature_) * travelled;
    const double predicted_variance =
        heading_variance_ + options_.heading_process_sigma * options_.heading_process_sigma * travelled;
    // Update with the frame's own, each by its variance.
    const double gain = predicted_variance / (predicted_variance + sigma * sigma);
    heading_ = predicted + gain * (measured - predicted);
    heading_variance_ = (1.0 - gain) * predicted_variance;
  }
  path_curvature_ = input.path_curvature;
  return heading_;
}

double PathTracker::FilteredOffset(const PathTrackingInput& input, double heading, double dt) {
  // The camera moved speed·dt since the last frame in the direction φ = ψ − atan(d κ) relative to the path.
  if (!offsets_.empty()) {
    const double travelled = speed_ * dt;
    const double direction = heading - std::atan(options_.camera_forward * curvature_);
    distance_ += travelled;
    drift_ += travelled * std::sin(direction);
  }
  offsets_.Add(distance_, input.lateral_m - drift_, input.lateral_sigma_m, input.arc);
  const CombinedObservation offset = offsets_.Combine();
  return offset.valid ? offset.value + drift_ : input.lateral_m;
}

PathTrackingCommand PathTracker::Update(const PathTrackingInput& input, bool prefer_image) {
  PathTrackingCommand command;
  const double dt = std::max(0.0, input.dt);
  if (!input.tracking) {
    // Lost: stop now; the wheels keep their angle (nothing to steer by).
    offsets_.Clear();
    steered_heading_ = heading_ = std::numeric_limits<double>::quiet_NaN();
    speed_ = 0.0;
    command.mode = SteeringMode::kStop;
    command.curvature = curvature_;
    command.speed = 0.0;
    return command;
  }
  double wanted = curvature_;
  if (input.metric && !prefer_image) {
    command.mode = SteeringMode::kPath;
    // The heading: the frame's own combined with the last one carried by the motion; with heading_from_offset the
    // frame's own, and the last frame's taken with its combined offset carries the window (this frame's own may come
    // with an offset the window corrects, and would carry the window's frames by its error).
    double heading = input.heading_error_rad;
    double carried_by = heading;
    if (options_.heading_from_offset) {
      if (std::isfinite(steered_heading_)) carried_by = steered_heading_;
    } else if (options_.heading_process_sigma > 0) {
      heading = carried_by = FilteredHeading(input, dt);
    }
    double lateral = input.lateral_m;
    if (options_.offset.process_sigma > 0) lateral = FilteredOffset(input, carried_by, dt);
    command.lateral_m = lateral;
    command.heading_error_rad = heading;
    if (options_.heading_from_offset && std::isfinite(input.heading_per_lateral)) {
      command.heading_error_rad += input.heading_per_lateral * (lateral - input.lateral_m);
    }
    steered_heading_ = command.heading_error_rad;
    wanted = CameraPointCurvature(lateral, command.heading_error_rad, options_);
  } else if (input.image_steering_valid) {
    command.mode = SteeringMode::kImage;
    wanted = -options_.image_gain * input.image_steering;
  } else {
    command.mode = SteeringMode::kImage;  // nothing new to steer by: hold the wheels
  }
  if (command.mode != SteeringMode::kPath) {  // the filtered offset and heading start again with the metric path
    offsets_.Clear();
    steered_heading_ = heading_ = std::numeric_limits<double>::quiet_NaN();
  }
  wanted = std::clamp(wanted, -options_.max_curvature, options_.max_curvature);
  const double step = options_.max_curvature_rate * dt;
  curvature_ = dt > 0 ? std::clamp(wanted, curvature_ - step, curvature_ + step) : wanted;

  double speed = options_.max_speed;
  if (std::abs(input.curvature_ahead) > 1e-9) {
    speed = std::min(speed, std::sqrt(options_.max_lateral_acceleration / std::abs(input.curvature_ahead)));
  }
  if (input.confidence < options_.confident || (!prefer_image && command.mode != SteeringMode::kPath)) {
    speed *= options_.uncertain_speed_fraction;
  }
  // Slowing down is immediate; speeding up is limited.
  speed_ = std::min(speed, speed_ + options_.max_acceleration * dt);
  command.curvature = curvature_;
  command.speed = speed_;
  return command;
}

}  // namespace retrace
