#pragma once

// A car-like vehicle carrying the camera, and a driver that follows a route.
//
// Kinematics: the bicycle model with the reference point on the rear axle (Rajamani, "Vehicle dynamics and
// control", 2012, §2.2, rear-axle form):  x' = v cos(theta),  y' = v sin(theta),  theta' = v tan(delta) / L,
// with steering angle delta and wheelbase L; integrated exactly along circular arcs.
//
// The camera sits `camera_forward` metres ahead of the rear axle at `camera_height`, looking forward and tilted
// down by `camera_tilt_deg`.
//
// A route is a polyline of waypoints on the ground (town frame). RoutePath rounds its corners with circular arcs
// (radius `corner_radius`), resamples it densely and computes a speed profile: the speed limit of the curvature,
// v <= sqrt(a_lat / |kappa|), then limited by the braking and acceleration rates in a backward and a forward pass
// so that the car slows down before turns and speeds up after them. The driver follows the path with pure pursuit
// (Coulter 1992: delta = atan(2 L sin(alpha) / l_d) towards a look-ahead point at distance l_d) shifted sideways by
// a lateral offset plus a seeded "wobble" (sum of two sines), so that a repeat drive never retraces the teach drive
// exactly.

#include <cstdint>
#include <vector>

#include "retrace/util/types.h"

namespace retrace {

// Ranges of the fields (here and in DriveOptions): Scenario::Check (sim/scenario.h, ScenarioKeyRanges).
struct VehicleOptions {
  // Distance between the axles (m).
  double wheelbase = 2.7;
  // Largest steering angle (degrees).
  double max_steering_deg = 35.0;
  // Camera placement: height above the ground, distance ahead of the rear axle (m), downward tilt (degrees).
  double camera_height = 1.5;
  double camera_forward = 1.8;
  double camera_tilt_deg = 5.0;
  // People walking with the car close to the camera (Booij 2007 §B.5.4's occlusion experiment): 0..kMaxEscorts
  // escorts at the spots of sim/town.h EscortSpot (0.6 m left and right of the camera, then ahead-left and
  // ahead-right, ...), moving occluders that block large parts of a panoramic view wherever the car drives.
  int escorts = 0;
};

struct VehicleState {
  Vector2d position = Vector2d::Zero();  // rear axle, town frame X, Y
  double heading = 0.0;                  // radians, counter-clockwise from +X (east)
  double speed = 0.0;                    // m/s
  double steering = 0.0;                 // radians, positive = left
};

class Vehicle {
 public:
  Vehicle(const VehicleOptions& options, const VehicleState& initial);

  // Advances by `dt` seconds with the given steering angle (clamped to the limit) and speed.
  void Step(double steering, double speed, double dt);

  const VehicleState& state() const { return state_; }
  const VehicleOptions& options() const { return options_; }
  // town_from_vehicle (x forward, y left, z up) and town_from_cam (x right, y down, z forward).
  Rigid3d TownFromVehicle() const;
  Rigid3d TownFromCamera() const;
  // vehicle_from_cam for a camera at (forward, 0, height) with the given tilt.
  static Rigid3d VehicleFromCamera(double forward, double height, double tilt_deg);

 private:
  VehicleOptions options_;
  VehicleState state_;
};

struct DriveOptions {
  // Top speed on straight streets (m/s).
  double max_speed = 8.0;
  // Lateral acceleration allowed in turns (m/s^2): sets how much the car slows down in curves.
  double max_lateral_acceleration = 1.5;
  // Longitudinal acceleration and braking limits (m/s^2).
  double max_acceleration = 1.5;
  double max_deceleration = 2.5;
  // Radius of the arcs that round the route's corners (m).
  double corner_radius = 7.0;
  // Start at rest (true) or at the profile speed (false).
  bool start_at_rest = false;
  // Constant sideways offset of the driven line, metres to the right of the route.
  double lateral_offset = 0.0;
  // Amplitude (m) and main wavelength (m) of the seeded sideways wobble (0 = none).
  double wobble_amplitude = 0.0;
  double wobble_wavelength = 40.0;
  // Seed of the wobble phases.
  uint64_t wobble_seed = 0;
};

// The dense, smoothed route with arc length, heading, curvature and speed profile.
class RoutePath {
 public:
  RoutePath(const std::vector<Vector2d>& waypoints, const DriveOptions& options);

  double length() const { return s_.back(); }
  // Interpolated position, heading (rad), curvature (1/m) and profile speed (m/s) at arc length s (clamped).
  Vector2d Position(double s) const;
  double Heading(double s) const;
  double Curvature(double s) const;
  double Speed(double s) const;
  // Arc length of the point of the path closest to `p`, searched in [s_min, s_max].
  double Project(const Vector2d& p, double s_min, double s_max) const;

 private:
  size_t Index(double s) const;
  std::vector<Vector2d> points_;
  std::vector<double> s_, heading_, curvature_, speed_;
};

// Pure-pursuit driver along a RoutePath with lateral offset and wobble.
class RouteDriver {
 public:
  RouteDriver(const RoutePath* path, const DriveOptions& drive, const VehicleOptions& vehicle);

  // The initial vehicle state: at the start of the (offset) path, aligned with it.
  VehicleState StartState() const;
  // Steering angle and speed for the current state; updates the progress along the path.
  void Control(const VehicleState& state, double* steering, double* speed);
  // Sideways offset of the driven line at arc length s (metres to the right).
  double Offset(double s) const;
  double progress() const { return progress_; }
  bool Finished() const { return progress_ >= path_->length() - 0.5; }
  // Distance (m) of `position` from the nearest point of the path near the current progress (0 on the route's
  // centre line of the lane; it grows without bound when the car drives on past the route's end).
  double DistanceFromPath(const Vector2d& position) const;

 private:
  Vector2d Target(double s) const;
  const RoutePath* path_;
  DriveOptions drive_;
  VehicleOptions vehicle_;
  double phase1_, phase2_;
  double progress_ = 0.0;
};

}  // namespace retrace
