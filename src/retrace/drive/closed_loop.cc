#include "retrace/drive/closed_loop.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include <fmt/format.h>
#include <opencv2/core.hpp>

#include "retrace/repeat/evaluation.h"

namespace retrace {

bool ClosedLoopOptions::Check(std::string* error) const {
  const auto fail = [error](const std::string& message) {
    if (error != nullptr) *error = message;
    return false;
  };
  // Plausible ranges (as the scenario's keys, sim/scenario.h): a car, a camera's frame rate, a run that ends.
  if (!(frame_period > 0 && frame_period <= 10)) {
    return fail(fmt::format("frame_period must be in (0, 10] s, got {}", frame_period));
  }
  std::string tracking_error;
  if (!tracking.Check(&tracking_error)) return fail("tracking: " + tracking_error);
  if (blackout_start < 0 || blackout_frames < 0) {
    return fail(fmt::format("blackout frames must be >= 0, got start {} and count {}", blackout_start, blackout_frames));
  }
  if (max_stopped_frames < 1) return fail(fmt::format("max_stopped_frames must be >= 1, got {}", max_stopped_frames));
  if (!(max_frames >= 1 && max_frames <= 1000000)) {
    return fail(fmt::format("max_frames must be in 1..1000000, got {}", max_frames));
  }
  if (!(max_deviation > 0 && max_deviation <= 1000)) {
    return fail(fmt::format("max_deviation must be in (0, 1000] m, got {}", max_deviation));
  }
  return true;
}

double ClosedLoopSummary::MedianDeviation() const {
  if (deviations.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::vector<double> d = deviations;
  std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
  return d[d.size() / 2];
}

double ClosedLoopSummary::MaxDeviation() const {
  if (deviations.empty()) return std::numeric_limits<double>::quiet_NaN();
  return *std::max_element(deviations.begin(), deviations.end());
}

PathTrackingFigures ClosedLoopSummary::Figures(double skip_m) const {
  PathTrackingFigures figures;
  std::vector<double> kept;
  for (size_t i = 0; i < deviations.size() && i < driven.size(); ++i) {
    if (driven[i] >= skip_m) kept.push_back(deviations[i]);
  }
  if (kept.empty()) return figures;
  figures.frames = static_cast<int>(kept.size());
  double squares = 0.0;
  for (double d : kept) squares += d * d;
  figures.rms = std::sqrt(squares / kept.size());
  std::sort(kept.begin(), kept.end());
  figures.p95 = kept[std::min(kept.size() - 1, static_cast<size_t>(0.95 * kept.size()))];
  figures.max = kept.back();
  return figures;
}

double DeviationFromPath(const PathTruth& truth, size_t taught_poses) {
  if (!truth.valid) return std::numeric_limits<double>::infinity();
  // The nearest point is the path's first or last camera centre, and the camera lies before or beyond it: its
  // distance to that point would count how far the car is from the end, not beside the path.
  const bool beyond_an_end = truth.along_index <= 0.0 || truth.along_index >= static_cast<double>(taught_poses) - 1.0;
  return beyond_an_end ? std::abs(truth.lateral_m) : truth.distance_m;
}

double DistanceToPath(const Vector3d& position, const std::vector<TimedPose>& taught, double* along) {
  const PathTruth truth = TruthAgainstTaughtPath(Rigid3d(Matrix3d::Identity(), position), taught, 0, taught.size());
  if (along != nullptr && truth.valid) *along = truth.along_index;
  return DeviationFromPath(truth, taught.size());
}

ClosedLoopSummary DriveClosedLoop(Simulator* simulator, Localizer* localizer, const Map& map,
                                  const std::vector<TimedPose>& taught, const ClosedLoopOptions& options,
                                  const std::function<void(const ClosedLoopStep&)>& on_step) {
  std::string error;
  if (!options.Check(&error)) throw std::invalid_argument("ClosedLoopOptions: " + error);
  // The route's last arcs: those whose end node has no arc leaving it.
  std::vector<arc_t> last_arcs;
  for (const MapArc& arc : map.arcs()) {
    if (map.ArcsFrom(arc.to).empty()) last_arcs.push_back(arc.id);
  }

  PathTracker tracker(options.tracking);
  const double wheelbase = simulator->scenario().vehicle.wheelbase;

  ClosedLoopSummary summary;
  int stopped_in_a_row = 0;
  double driven = 0.0;
  SimFrame view = simulator->Step(0.0, 0.0, 0.0);
  Vector3d last_position = view.world_from_cam.translation;
  for (int i = 0; i < options.max_frames; ++i) {
    Frame frame;
    frame.index = frame.source_index = static_cast<size_t>(i);
    frame.timestamp = view.timestamp;
    frame.image = view.image;
    if (i >= options.blackout_start && i < options.blackout_start + options.blackout_frames) {
      frame.image = cv::Mat::zeros(view.image.size(), view.image.type());
    }
    const FrameResult result = localizer->ProcessFrame(frame);
    ++summary.frames;
    driven += (view.world_from_cam.translation - last_position).norm();
    last_position = view.world_from_cam.translation;
    summary.tracking += result.state == LocalizerState::kTracking;

    PathTrackingInput input;
    input.tracking = result.state == LocalizerState::kTracking;
    input.confidence = result.confidence;
    input.metric = result.path.valid;
    // The frame's own offset: the path tracker combines the recent frames itself, carried by the motion it commanded.
    input.lateral_m = result.path.frame_lateral_m;
    input.lateral_sigma_m = result.path.frame_lateral_sigma_m;
    input.arc = result.arc;  // kInvalidArcId (-1) when not tracking
    input.heading_error_rad = result.path.heading_error_rad;
    input.heading_sigma_rad = result.path.heading_sigma_rad;
    input.path_curvature = result.path.curvature;
    input.heading_per_lateral = result.path.heading_per_lateral;
    input.curvature_ahead = result.path.curvature_ahead;  // 0 when the frame has no metric path
    input.image_steering_valid = result.steering_valid;
    input.image_steering = result.steering;
    input.dt = options.frame_period;

    ClosedLoopStep step;
    step.view = &view;
    step.result = &result;
    step.command = tracker.Update(input, options.control == ClosedLoopControl::kImage);
    step.wheels = std::atan(wheelbase * step.command.curvature);
    summary.path_frames += step.command.mode == SteeringMode::kPath;
    summary.stopped_frames += step.command.speed <= 0;
    stopped_in_a_row = step.command.speed <= 0 ? stopped_in_a_row + 1 : 0;
    bool past_end = false;
    if (taught.size() >= 2) {
      const PathTruth truth = TruthAgainstTaughtPath(view.world_from_cam, taught, 0, taught.size());
      step.deviation = DeviationFromPath(truth, taught.size());
      step.along = truth.along_index;
      step.true_lateral = truth.lateral_m;
      step.true_heading_error = truth.heading_error_rad;
      summary.deviations.push_back(step.deviation);
      summary.driven.push_back(driven);
      past_end = step.along >= static_cast<double>(taught.size()) - 1.5;
      summary.left_path = step.deviation > options.max_deviation;
    } else {
      past_end = result.state == LocalizerState::kTracking && result.position_valid && result.position_on_arc >= 1.0 &&
                 std::find(last_arcs.begin(), last_arcs.end(), result.arc) != last_arcs.end();
    }
    if (on_step) on_step(step);
    if (past_end) {
      summary.reached_end = true;
      break;
    }
    if (summary.left_path) break;
    summary.left_route = simulator->OffRoute();
    if (summary.left_route) break;
    summary.stalled = stopped_in_a_row >= options.max_stopped_frames;
    if (summary.stalled) break;
    view = simulator->Step(step.wheels, step.command.speed, options.frame_period);
  }
  return summary;
}

}  // namespace retrace
