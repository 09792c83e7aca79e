#pragma once

// The simulator: a scenario's world, vehicle and renderer, driven frame by frame along the route (autopilot) or
// step by step by an external controller (closed loop).
//
// Output world frame ("world"): the frame of a camera standing on the ground at the start of the route, looking
// along the route's initial direction, level: x right, y down (gravity), z forward, origin on the ground. Poses
// written by the simulator are world_from_cam; the first teach pose is near identity (a translation of the camera
// height upwards, -camera_height along y, plus the camera's forward offset and tilt). Teach and repeat recordings of
// one scenario share this frame, so their ground truth compares directly.
//
// Escorts (vehicle.escorts, sim/town.h AddEscorts) walk with the camera: every rendered frame places them around the
// camera's pose of that frame, whether the autopilot, a closed-loop controller (Step) or RenderAt set it.

#include <filesystem>
#include <memory>
#include <string>

#include <opencv2/core.hpp>

#include "retrace/sim/renderer.h"
#include "retrace/sim/scenario.h"
#include "retrace/sim/scene.h"
#include "retrace/sim/town.h"
#include "retrace/sim/vehicle.h"

namespace retrace {

struct SimFrame {
  cv::Mat image;
  double timestamp = 0.0;  // seconds since the first frame
  Rigid3d world_from_cam;
  Rigid3d town_from_cam;
  VehicleState vehicle;
  double progress = 0.0;   // metres along the route
};

class Simulator {
 public:
  // Builds the world (takes a few hundred milliseconds for the town) and places the vehicle at the route's start.
  // Throws std::invalid_argument when the scenario fails Scenario::Check (files and options are checked before).
  explicit Simulator(const Scenario& scenario);
  ~Simulator();

  const Scenario& scenario() const { return scenario_; }
  const CameraModel& camera() const { return renderer_->camera(); }
  Scene& scene() { return *scene_; }
  const TownLayout& layout() const { return layout_; }
  const RoutePath& route() const { return *route_; }
  const Rigid3d& town_from_world() const { return town_from_world_; }
  const VehicleState& vehicle_state() const { return vehicle_->state(); }
  double time() const { return time_; }
  // Pixels re-rendered with sub-samples (anti-aliasing of edges) in the last frame.
  size_t last_supersampled_pixels() const { return renderer_->last_supersampled_pixels(); }

  // Autopilot: renders the current view into `frame`, then drives one frame period along the route. Returns false
  // (and leaves `frame` untouched) when the route is finished or the scenario's frame count is reached, whichever
  // comes first: the car never drives on past the route's end (out of the town).
  bool NextFrame(SimFrame* frame);
  // The autopilot stopped because the route was finished (NextFrame returned false at the route's end, possibly
  // before the scenario's frame count).
  bool RouteFinished() const;
  // Number of frames the autopilot will produce: the scenario's frame count or, when the route ends before it (or
  // num_frames = 0), the frames of the whole route estimated from the speed profile.
  int ExpectedFrames() const;

  // Closed loop: applies `steering` (radians, positive left) and `speed` (m/s) for `dt` seconds, then renders.
  SimFrame Step(double steering, double speed, double dt);
  // Closed loop: the car has left the world built around the route: past the route's end (RouteFinished) or
  // farther than kMaxDistanceFromRoute from it, where the town ends or a block begins. A controller should stop.
  bool OffRoute() const;
  static constexpr double kMaxDistanceFromRoute = 20.0;  // metres from the route's lane

  // Renders the world at `time` from any camera pose given in the world frame (for tests and tools); the escorts
  // (vehicle.escorts) walk around that camera as they do around the car's.
  cv::Mat RenderAt(const Rigid3d& world_from_cam, double time, uint64_t noise_seed = 0);

 private:
  SimFrame RenderCurrent();
  void Drive(double dt);

  Scenario scenario_;
  std::unique_ptr<Scene> scene_;
  TownLayout layout_;
  std::unique_ptr<RoutePath> route_;
  std::unique_ptr<RouteDriver> driver_;
  std::unique_ptr<Vehicle> vehicle_;
  std::unique_ptr<Renderer> renderer_;
  Rigid3d town_from_world_;
  double time_ = 0.0;
  int frame_index_ = 0;
};

// The waypoints a scenario's route resolves to in `layout` (town frame).
std::vector<Vector2d> ResolveRoute(const Scenario& scenario, const TownLayout& layout);

// Simulator(scenario).town_from_world() without building the town: the pose of a recorded drive's world frame (its
// poses.txt) in the town frame (x east, y north, z up).
Rigid3d TownFromWorld(const Scenario& scenario);

}  // namespace retrace
