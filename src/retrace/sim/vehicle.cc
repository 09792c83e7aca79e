#include "retrace/sim/vehicle.h"

#include <algorithm>
#include <cmath>

#include "retrace/sim/procedural_texture.h"

namespace retrace {
namespace {

double WrapAngle(double a) {
  while (a > M_PI) a -= 2.0 * M_PI;
  while (a < -M_PI) a += 2.0 * M_PI;
  return a;
}

}  // namespace

Vehicle::Vehicle(const VehicleOptions& options, const VehicleState& initial) : options_(options), state_(initial) {}

void Vehicle::Step(double steering, double speed, double dt) {
  const double limit = options_.max_steering_deg * M_PI / 180.0;
  state_.steering = std::clamp(steering, -limit, limit);
  state_.speed = speed;
  const double distance = speed * dt;
  const double curvature = std::tan(state_.steering) / options_.wheelbase;
  const double turn = distance * curvature;
  if (std::abs(turn) < 1e-9) {
    state_.position += distance * Vector2d(std::cos(state_.heading), std::sin(state_.heading));
  } else {
    // Exact integration along the circular arc of radius 1 / curvature.
    const double r = 1.0 / curvature;
    state_.position += r * Vector2d(std::sin(state_.heading + turn) - std::sin(state_.heading),
                                    -std::cos(state_.heading + turn) + std::cos(state_.heading));
  }
  state_.heading = WrapAngle(state_.heading + turn);
}

Rigid3d Vehicle::TownFromVehicle() const {
  const double c = std::cos(state_.heading), s = std::sin(state_.heading);
  Matrix3d r;
  r << c, -s, 0, s, c, 0, 0, 0, 1;
  return Rigid3d(r, Vector3d(state_.position.x(), state_.position.y(), 0.0));
}

Rigid3d Vehicle::VehicleFromCamera(double forward, double height, double tilt_deg) {
  const double t = tilt_deg * M_PI / 180.0;
  // Camera axes in the vehicle frame: z forward tilted down, x right (-y of the vehicle), y = z x x.
  const Vector3d z(std::cos(t), 0.0, -std::sin(t));
  const Vector3d x(0.0, -1.0, 0.0);
  const Vector3d y = z.cross(x);
  Matrix3d r;
  r.col(0) = x;
  r.col(1) = y;
  r.col(2) = z;
  return Rigid3d(r, Vector3d(forward, 0.0, height));
}

Rigid3d Vehicle::TownFromCamera() const {
  return TownFromVehicle() *
         VehicleFromCamera(options_.camera_forward, options_.camera_height, options_.camera_tilt_deg);
}

RoutePath::RoutePath(const std::vector<Vector2d>& waypoints, const DriveOptions& options) {
  // Remove repeated points.
  std::vector<Vector2d> w;
  for (const auto& p : waypoints) {
    if (w.empty() || (p - w.back()).norm() > 1e-6) w.push_back(p);
  }
  if (w.size() < 2) w = {w.empty() ? Vector2d(0, 0) : w[0], (w.empty() ? Vector2d(0, 0) : w[0]) + Vector2d(1, 0)};
  // Round every interior corner with an arc tangent to both segments.
  std::vector<Vector2d> coarse = {w[0]};
  for (size_t k = 1; k + 1 < w.size(); ++k) {
    const Vector2d d_in = (w[k] - w[k - 1]).normalized(), d_out = (w[k + 1] - w[k]).normalized();
    const double turn = std::atan2(d_in.x() * d_out.y() - d_in.y() * d_out.x(), d_in.dot(d_out));
    double radius = options.corner_radius;
    double cut = radius * std::tan(std::abs(turn) / 2.0);
    const double room = 0.5 * std::min((w[k] - w[k - 1]).norm(), (w[k + 1] - w[k]).norm());
    if (cut > room) {
      cut = room;
      radius = cut / std::max(1e-9, std::tan(std::abs(turn) / 2.0));
    }
    if (std::abs(turn) < 1e-6 || cut < 1e-6) {
      coarse.push_back(w[k]);
      continue;
    }
    const Vector2d start = w[k] - cut * d_in;
    const Vector2d left(-d_in.y(), d_in.x());
    const Vector2d centre = start + (turn > 0 ? 1.0 : -1.0) * radius * left;
    const int steps = std::max(2, static_cast<int>(std::abs(turn) * radius / 0.25));
    const Vector2d r0 = start - centre;
    for (int i = 0; i <= steps; ++i) {
      const double a = turn * i / steps;
      coarse.push_back(centre + Vector2d(std::cos(a) * r0.x() - std::sin(a) * r0.y(),
                                         std::sin(a) * r0.x() + std::cos(a) * r0.y()));
    }
  }
  coarse.push_back(w.back());
  // Resample at <= 0.25 m.
  points_ = {coarse[0]};
  for (size_t k = 1; k < coarse.size(); ++k) {
    const Vector2d a = coarse[k - 1], b = coarse[k];
    const int n = std::max(1, static_cast<int>(std::ceil((b - a).norm() / 0.25)));
    for (int i = 1; i <= n; ++i) {
      const Vector2d p = a + (b - a) * (static_cast<double>(i) / n);
      if ((p - points_.back()).norm() > 1e-6) points_.push_back(p);
    }
  }
  const size_t n = points_.size();
  s_.assign(n, 0.0);
  heading_.assign(n, 0.0);
  curvature_.assign(n, 0.0);
  for (size_t i = 1; i < n; ++i) s_[i] = s_[i - 1] + (points_[i] - points_[i - 1]).norm();
  for (size_t i = 0; i < n; ++i) {
    const Vector2d d = points_[std::min(i + 1, n - 1)] - points_[i > 0 ? i - 1 : 0];
    heading_[i] = std::atan2(d.y(), d.x());
  }
  for (size_t i = 1; i + 1 < n; ++i) {
    // Curvature from the heading change over a +-1 m window.
    size_t a = i, b = i;
    while (a > 0 && s_[i] - s_[a] < 1.0) --a;
    while (b + 1 < n && s_[b] - s_[i] < 1.0) ++b;
    curvature_[i] = WrapAngle(heading_[b] - heading_[a]) / std::max(1e-6, s_[b] - s_[a]);
  }
  // Speed profile: curvature limit, then braking (backward) and acceleration (forward) limits.
  speed_.assign(n, options.max_speed);
  for (size_t i = 0; i < n; ++i) {
    if (std::abs(curvature_[i]) > 1e-6) {
      speed_[i] = std::min(speed_[i], std::sqrt(options.max_lateral_acceleration / std::abs(curvature_[i])));
    }
  }
  for (size_t i = n - 1; i-- > 0;) {
    const double ds = s_[i + 1] - s_[i];
    speed_[i] = std::min(speed_[i], std::sqrt(speed_[i + 1] * speed_[i + 1] + 2.0 * options.max_deceleration * ds));
  }
  if (options.start_at_rest) speed_[0] = 0.0;
  for (size_t i = 1; i < n; ++i) {
    const double ds = s_[i] - s_[i - 1];
    speed_[i] = std::min(speed_[i], std::sqrt(speed_[i - 1] * speed_[i - 1] + 2.0 * options.max_acceleration * ds));
  }
  if (options.start_at_rest) speed_[0] = std::min(speed_[1], 0.5);  // get going
}

size_t RoutePath::Index(double s) const {
  const auto it = std::upper_bound(s_.begin(), s_.end(), s);
  const size_t i = it == s_.begin() ? 1 : static_cast<size_t>(it - s_.begin());
  return std::min(i, s_.size() - 1);
}

Vector2d RoutePath::Position(double s) const {
  s = std::clamp(s, 0.0, length());
  const size_t i = Index(s);
  const double a = (s - s_[i - 1]) / std::max(1e-12, s_[i] - s_[i - 1]);
  return points_[i - 1] + a * (points_[i] - points_[i - 1]);
}

double RoutePath::Heading(double s) const {
  s = std::clamp(s, 0.0, length());
  const size_t i = Index(s);
  const double a = (s - s_[i - 1]) / std::max(1e-12, s_[i] - s_[i - 1]);
  return heading_[i - 1] + a * WrapAngle(heading_[i] - heading_[i - 1]);
}

double RoutePath::Curvature(double s) const { return curvature_[Index(std::clamp(s, 0.0, length()))]; }

double RoutePath::Speed(double s) const {
  s = std::clamp(s, 0.0, length());
  const size_t i = Index(s);
  const double a = (s - s_[i - 1]) / std::max(1e-12, s_[i] - s_[i - 1]);
  return speed_[i - 1] + a * (speed_[i] - speed_[i - 1]);
}

double RoutePath::Project(const Vector2d& p, double s_min, double s_max) const {
  double best = std::max(0.0, s_min), best_d2 = std::numeric_limits<double>::infinity();
  const size_t a = Index(std::max(0.0, s_min)) - 1, b = Index(std::min(length(), s_max));
  for (size_t i = a; i < b; ++i) {
    const Vector2d d = points_[i + 1] - points_[i];
    const double t = std::clamp((p - points_[i]).dot(d) / std::max(1e-12, d.squaredNorm()), 0.0, 1.0);
    const double d2 = (points_[i] + t * d - p).squaredNorm();
    if (d2 < best_d2) {
      best_d2 = d2;
      best = s_[i] + t * (s_[i + 1] - s_[i]);
    }
  }
  return best;
}

RouteDriver::RouteDriver(const RoutePath* path, const DriveOptions& drive, const VehicleOptions& vehicle)
    : path_(path), drive_(drive), vehicle_(vehicle) {
  SimRandom rng(HashCombine(drive.wobble_seed, 0x30bb1e));
  phase1_ = rng.Uniform(0.0, 2.0 * M_PI);
  phase2_ = rng.Uniform(0.0, 2.0 * M_PI);
}

double RouteDriver::Offset(double s) const {
  double offset = drive_.lateral_offset;
  if (drive_.wobble_amplitude > 0.0) {
    const double k = 2.0 * M_PI / drive_.wobble_wavelength;
    offset += drive_.wobble_amplitude * (0.7 * std::sin(k * s + phase1_) + 0.3 * std::sin(2.7 * k * s + phase2_));
  }
  return offset;
}

Vector2d RouteDriver::Target(double s) const {
  const double h = path_->Heading(s);
  return path_->Position(s) + Offset(s) * Vector2d(std::sin(h), -std::cos(h));
}

VehicleState RouteDriver::StartState() const {
  VehicleState state;
  state.position = Target(0.0);
  const Vector2d ahead = Target(std::min(path_->length(), 1.0));
  state.heading = std::atan2(ahead.y() - state.position.y(), ahead.x() - state.position.x());
  state.speed = path_->Speed(0.0);
  return state;
}

double RouteDriver::DistanceFromPath(const Vector2d& position) const {
  return (position - path_->Position(path_->Project(position, progress_ - 1.0, progress_ + 5.0))).norm();
}

void RouteDriver::Control(const VehicleState& state, double* steering, double* speed) {
  progress_ = path_->Project(state.position, progress_ - 1.0, progress_ + 5.0);
  *speed = path_->Speed(progress_);
  // Pure pursuit (Coulter 1992): steer on the arc through the look-ahead point.
  const double lookahead = std::max(4.0, 1.2 * state.speed);
  const Vector2d target = Target(progress_ + lookahead);
  const Vector2d d = target - state.position;
  const double alpha = WrapAngle(std::atan2(d.y(), d.x()) - state.heading);
  *steering = std::atan2(2.0 * vehicle_.wheelbase * std::sin(alpha), std::max(1e-6, d.norm()));
}

}  // namespace retrace
