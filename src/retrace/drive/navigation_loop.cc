#include "retrace/drive/navigation_loop.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include <fmt/format.h>

namespace retrace {

bool NavigationLoopOptions::Check(std::string* error) const {
  const auto fail = [error](const std::string& message) {
    if (error != nullptr) *error = message;
    return false;
  };
  if (!(frame_period > 0 && frame_period <= 10)) {
    return fail(fmt::format("frame_period must be in (0, 10] s, got {}", frame_period));
  }
  if (!(max_frames >= 1 && max_frames <= 1000000)) {
    return fail(fmt::format("max_frames must be in 1..1000000, got {}", max_frames));
  }
  if (max_stopped_frames < 1) return fail(fmt::format("max_stopped_frames must be >= 1, got {}", max_stopped_frames));
  return true;
}

double DistanceToPolyline(const std::vector<Vector2d>& points, const Vector2d& p) {
  if (points.size() == 1) return (points[0] - p).norm();
  double best = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i + 1 < points.size(); ++i) {
    const Vector2d ab = points[i + 1] - points[i];
    const double along = ab.squaredNorm() > 0 ? std::clamp((p - points[i]).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0;
    best = std::min(best, (points[i] + along * ab - p).norm());
  }
  return best;
}

NavigationLoopSummary DriveToGoal(Simulator* simulator, Navigator* navigator, const NavigationLoopOptions& options,
                                  const std::unordered_map<node_t, Vector2d>& key_image_places,
                                  const std::function<void(const NavigationLoopStep&)>& on_step) {
  std::string error;
  if (!options.Check(&error)) throw std::invalid_argument("NavigationLoopOptions: " + error);
  const double wheelbase = simulator->scenario().vehicle.wheelbase;
  NavigationLoopSummary summary;
  int stopped_in_a_row = 0;
  double off_plan_sum = 0.0;
  int off_plan_frames = 0;
  SimFrame view = simulator->Step(0.0, 0.0, 0.0);
  for (int i = 0; i < options.max_frames; ++i) {
    const NavigationStep step = navigator->ProcessImage(view.image);
    ++summary.frames;
    const Vector2d position = view.town_from_cam.translation.head<2>();
    if (!summary.camera_positions.empty()) summary.path_length_m += (position - summary.camera_positions.back()).norm();
    summary.camera_positions.push_back(position);
    if (!key_image_places.empty()) {
      std::vector<Vector2d> plan;
      for (const node_t node : navigator->planned_path().nodes) {
        if (const auto place = key_image_places.find(node); place != key_image_places.end()) plan.push_back(place->second);
      }
      if (!plan.empty()) {
        const double off_plan = DistanceToPolyline(plan, position);
        summary.max_off_plan_m = std::max(summary.max_off_plan_m, off_plan);
        off_plan_sum += off_plan;
        ++off_plan_frames;
      }
    }
    summary.frames_without_heading += step.state == NavigationState::kNavigating && !step.heading.has_value();
    summary.image_steering_frames += step.image_steering;
    summary.replans = navigator->replans();

    NavigationLoopStep loop_step;
    loop_step.view = &view;
    loop_step.step = &step;
    loop_step.wheels = std::atan(wheelbase * step.curvature);
    if (on_step) on_step(loop_step);

    summary.relocalizations = navigator->relocalizations();
    if (step.state == NavigationState::kAtGoal) {
      summary.reached_goal = true;
      break;
    }
    summary.left_streets = !simulator->layout().OnStreets(simulator->vehicle_state().position);
    if (summary.left_streets) break;
    stopped_in_a_row = step.speed <= 0 ? stopped_in_a_row + 1 : 0;
    summary.stalled = stopped_in_a_row >= options.max_stopped_frames;
    if (summary.stalled) break;
    view = simulator->Step(loop_step.wheels, step.speed, options.frame_period);
  }
  if (off_plan_frames > 0) summary.mean_off_plan_m = off_plan_sum / off_plan_frames;
  return summary;
}

}  // namespace retrace
