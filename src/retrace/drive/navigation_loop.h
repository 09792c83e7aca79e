#pragma once

// Closed-loop navigation in the simulator (Booij 2007 §B.4-B.5): the simulated car, placed where its scenario's drive
// starts, is steered by the Navigator alone — frame by frame, the heading towards the subgoal turned into a curvature
// and a speed — until the navigator stops at the goal or the drive gives up. The front wheels are set to atan(L κ)
// (L the scenario's wheelbase, positive left) for one frame period.
//
// The car may leave the scenario's route (it drives to a goal on another one), so the drive ends where the streets
// end instead (TownLayout OnStreets: inside a block or outside the town), not at Simulator::OffRoute.

#include <functional>
#include <unordered_map>
#include <vector>

#include "retrace/nav/navigator.h"
#include "retrace/sim/simulator.h"

namespace retrace {

struct NavigationLoopOptions {
  double frame_period = 0.1;  // seconds between frames: the car drives this long with one command
  int max_frames = 3000;      // the drive gives up after this many frames ...
  int max_stopped_frames = 50;  // ... or this many in a row standing still (not localized, no path)

  bool Check(std::string* error = nullptr) const;
};

// One frame of a navigation drive.
struct NavigationLoopStep {
  const SimFrame* view = nullptr;         // what the camera saw and where it was (ground truth)
  const NavigationStep* step = nullptr;   // what the navigator made of it
  double wheels = 0.0;                    // steering applied after this frame (radians, positive left)
};

struct NavigationLoopSummary {
  int frames = 0;
  bool reached_goal = false;   // the navigator stopped at the goal
  bool stalled = false;        // stood still for max_stopped_frames frames
  bool left_streets = false;   // drove into a block or out of the town
  int relocalizations = 0;     // recoveries after max_misses images without a heading (not the first localization)
  int frames_without_heading = 0;
  int image_steering_frames = 0;  // steered by eq. (10) on a taught arc of the plan (the localizer beneath)
  int replans = 0;                // plans made again because the localizer tracked an arc off the plan
  double path_length_m = 0.0;             // driven by the camera
  std::vector<Vector2d> camera_positions;  // per frame, town frame (x east, y north)
  // With the key-images' true places: the camera's largest distance from the polyline through the places of the
  // path planned at that frame. A wrong turn leaves it by a street's length. 0 without places.
  double max_off_plan_m = 0.0;
  double mean_off_plan_m = 0.0;  // ... and its mean over the frames (how closely the car keeps to the taught line)
};

// Distance of `p` from the polyline through `points` (from the point when there is one, infinite when none).
double DistanceToPolyline(const std::vector<Vector2d>& points, const Vector2d& p);

// Drives `simulator` (at its scenario's start) with `navigator`'s commands. `key_image_places` (town frame, may be
// empty) are the key-images' true places for max_off_plan_m. `on_step` (optional) sees every frame.
NavigationLoopSummary DriveToGoal(Simulator* simulator, Navigator* navigator, const NavigationLoopOptions& options,
                                  const std::unordered_map<node_t, Vector2d>& key_image_places = {},
                                  const std::function<void(const NavigationLoopStep&)>& on_step = {});

}  // namespace retrace
