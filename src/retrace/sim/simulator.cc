#include "retrace/sim/simulator.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>

#include <Eigen/Geometry>

#include "retrace/sim/procedural_texture.h"
#include "retrace/sim/scene_file.h"

namespace retrace {

std::vector<Vector2d> ResolveRoute(const Scenario& scenario, const TownLayout& layout) {
  const RouteSpec& r = scenario.route;
  if (r.type == "waypoints") return r.waypoints;
  std::vector<Vector2d> junctions;
  if (r.type == "loop") {
    junctions = LoopRouteJunctions(layout, r.loop_i0, r.loop_j0, r.loop_i1, r.loop_j1);
  } else if (r.type == "crossing") {
    junctions = FigureEightJunctions(layout, r.loop_i0, r.loop_j0);
  } else if (r.type == "junctions") {
    for (const auto& [i, j] : r.junctions) junctions.push_back(layout.Junction(i, j));
  } else {
    junctions = RandomRouteJunctions(layout, r.segments, scenario.seed);
  }
  return OffsetPolyline(junctions, layout.lane_offset());
}

namespace {

// World frame: a level camera on the ground at the route's start, looking along the route.
Rigid3d TownFromWorldAtStart(const Scenario& scenario, const RoutePath& route) {
  VehicleState start;
  start.position = route.Position(0.0);
  start.heading = route.Heading(0.0);
  return Vehicle(scenario.vehicle, start).TownFromVehicle() * Vehicle::VehicleFromCamera(0.0, 0.0, 0.0);
}

// The escorts' carrier under a camera (town.h AddEscorts): on the ground `camera_height` below it, x along its line of
// sight turned level, z up.
Rigid3d CarrierUnderCamera(const Rigid3d& town_from_cam, double camera_height) {
  const Vector3d forward = town_from_cam.rotation.col(2);
  const double yaw = std::atan2(forward.y(), forward.x());
  return Rigid3d(Eigen::AngleAxisd(yaw, Vector3d::UnitZ()).toRotationMatrix(),
                 town_from_cam.translation - Vector3d(0.0, 0.0, camera_height));
}

}  // namespace

Rigid3d TownFromWorld(const Scenario& scenario) {
  const TownLayout layout = scenario.scene_file.empty() ? PlanTownLayout(scenario.town) : TownLayout();
  return TownFromWorldAtStart(scenario, RoutePath(ResolveRoute(scenario, layout), scenario.drive));
}

Simulator::Simulator(const Scenario& scenario) : scenario_(scenario) {
  // Out-of-range values would exhaust the machine (threads, memory) before anything else noticed them.
  if (const std::optional<ScenarioProblem> problem = scenario.Check()) {
    throw std::invalid_argument("Simulator: invalid scenario: " + problem->ToString());
  }
  scene_ = std::make_unique<Scene>();
  if (scenario.scene_file.empty()) {
    layout_ = BuildTown(scenario.town, scene_.get());
  } else {
    SceneFileOptions options;
    options.scale = scenario.scene_scale;
    options.y_up = scenario.scene_y_up;
    LoadSceneFile(scenario.scene_file, options, scene_.get());
    scene_->set_sky(SkyType::kProcedural);
    scene_->Commit();
  }
  route_ = std::make_unique<RoutePath>(ResolveRoute(scenario, layout_), scenario.drive);
  town_from_world_ = TownFromWorldAtStart(scenario, *route_);
  if (!scenario.markers.empty()) {
    Material glow;
    glow.emissive = true;
    glow.color = Vector3f::Constant(static_cast<float>(scenario.marker_brightness));
    const int material = scene_->AddMaterial(glow);
    Mesh markers;
    for (const Vector3d& p : scenario.markers) {
      const Vector3f centre = (town_from_world_ * p).cast<float>();
      markers.AddBlob(centre, Vector3f::Constant(static_cast<float>(scenario.marker_radius)), 3, 0.0f, 0, 1.0f,
                      material);
    }
    scene_->AddStaticMesh(markers);
    scene_->Commit();
  }
  if (scenario.vehicle.escorts > 0) {
    // Seeded by the drive, not the town: the same people walk with the teach and the repeat drive.
    AddEscorts(scenario.vehicle.escorts, scenario.seed, scene_.get());
    scene_->Commit();
  }
  driver_ = std::make_unique<RouteDriver>(route_.get(), scenario.drive, scenario.vehicle);
  vehicle_ = std::make_unique<Vehicle>(scenario.vehicle, driver_->StartState());
  const std::unique_ptr<CameraModel> camera = scenario.camera.MakeCamera();
  renderer_ = std::make_unique<Renderer>(*camera, scenario.render);
  time_ = 0.0;
}

Simulator::~Simulator() = default;

int Simulator::ExpectedFrames() const {
  // Integrate the travel time of the speed profile.
  double t = 0.0;
  for (double s = 0.0; s < route_->length(); s += 0.5) t += 0.5 / std::max(0.3, route_->Speed(s));
  const int route_frames = static_cast<int>(t * scenario_.frame_rate) + 1;
  return scenario_.num_frames > 0 ? std::min(scenario_.num_frames, route_frames) : route_frames;
}

bool Simulator::RouteFinished() const { return driver_->Finished(); }

SimFrame Simulator::RenderCurrent() {
  SimFrame frame;
  frame.timestamp = time_;
  frame.town_from_cam = vehicle_->TownFromCamera();
  frame.world_from_cam = town_from_world_.Inverse() * frame.town_from_cam;
  frame.vehicle = vehicle_->state();
  frame.progress = driver_->progress();
  scene_->SetCarrier(CarrierUnderCamera(frame.town_from_cam, scenario_.vehicle.camera_height));
  scene_->SetTime(time_ + scenario_.time_offset);
  const uint64_t noise_seed =
      HashCombine(HashCombine(scenario_.seed, scenario_.drive.wobble_seed + 0x9e37), static_cast<uint64_t>(frame_index_));
  frame.image = renderer_->Render(*scene_, frame.town_from_cam, scenario_.lighting, scenario_.sensor, noise_seed);
  ++frame_index_;
  return frame;
}

void Simulator::Drive(double dt) {
  // Physics and control at <= 20 ms steps.
  const int steps = std::max(1, static_cast<int>(std::ceil(dt / 0.02)));
  for (int k = 0; k < steps; ++k) {
    double steering = 0.0, speed = 0.0;
    driver_->Control(vehicle_->state(), &steering, &speed);
    vehicle_->Step(steering, speed, dt / steps);
  }
  time_ += dt;
}

bool Simulator::NextFrame(SimFrame* frame) {
  if (scenario_.num_frames > 0 && frame_index_ >= scenario_.num_frames) return false;
  if (driver_->Finished()) return false;
  *frame = RenderCurrent();
  Drive(1.0 / scenario_.frame_rate);
  return true;
}

SimFrame Simulator::Step(double steering, double speed, double dt) {
  const int steps = std::max(1, static_cast<int>(std::ceil(dt / 0.02)));
  for (int k = 0; k < steps; ++k) vehicle_->Step(steering, speed, dt / steps);
  time_ += dt;
  double unused_steering, unused_speed;
  driver_->Control(vehicle_->state(), &unused_steering, &unused_speed);  // keeps the progress up to date
  return RenderCurrent();
}

bool Simulator::OffRoute() const {
  return driver_->Finished() || driver_->DistanceFromPath(vehicle_->state().position) > kMaxDistanceFromRoute;
}

cv::Mat Simulator::RenderAt(const Rigid3d& world_from_cam, double time, uint64_t noise_seed) {
  const Rigid3d town_from_cam = town_from_world_ * world_from_cam;
  scene_->SetCarrier(CarrierUnderCamera(town_from_cam, scenario_.vehicle.camera_height));
  scene_->SetTime(time + scenario_.time_offset);
  return renderer_->Render(*scene_, town_from_cam, scenario_.lighting, scenario_.sensor, noise_seed);
}

}  // namespace retrace
