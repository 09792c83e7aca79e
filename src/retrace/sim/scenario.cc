#include "retrace/sim/scenario.h"

#include <cmath>

#include <fmt/format.h>

#include "retrace/camera/equirectangular_camera.h"
#include "retrace/camera/unified_camera.h"

namespace retrace {

bool CameraSpec::Check() const {
  if (width < 8 || height < 8 || width > 8192 || height > 8192) return false;
  if (model == "perspective") return (fx > 0.0 || (hfov_deg > 1.0 && hfov_deg < 179.0)) && fy >= 0.0;
  if (model == "unified") {
    const double half = 0.5 * hfov_deg * M_PI / 180.0;
    return xi >= 0.0 && (fx > 0.0 || (hfov_deg > 1.0 && std::cos(half) + xi > 0.05));
  }
  return model == "equirectangular";
}

std::unique_ptr<CameraModel> CameraSpec::MakeCamera() const {
  if (model == "equirectangular") return std::make_unique<EquirectangularCamera>(width, height);
  const double c_x = cx >= 0.0 ? cx : 0.5 * (width - 1);
  const double c_y = cy >= 0.0 ? cy : 0.5 * (height - 1);
  if (model == "unified") {
    // A ray at angle theta from the axis lands at radius f sin(theta) / (cos(theta) + xi) (Mei 2007).
    const double half = 0.5 * hfov_deg * M_PI / 180.0;
    const double f = fx > 0.0 ? fx : 0.5 * width * (std::cos(half) + xi) / std::sin(half);
    return std::make_unique<UnifiedCamera>(width, height, xi, f, fy > 0.0 ? fy : f, c_x, c_y, 0.0, distortion);
  }
  const double f = fx > 0.0 ? fx : 0.5 * width / std::tan(0.5 * hfov_deg * M_PI / 180.0);
  const double f_y = fy > 0.0 ? fy : f;
  return std::make_unique<PerspectiveCamera>(width, height, f, f_y, c_x, c_y, 0.0, distortion);
}

bool RouteSpec::Check() const {
  if (type == "auto") return segments >= 1;
  if (type == "loop") return loop_i0 >= 0 && loop_j0 >= 0 && loop_i1 > loop_i0 && loop_j1 > loop_j0;
  if (type == "crossing") return loop_i0 >= 0 && loop_j0 >= 0;
  if (type == "waypoints") return waypoints.size() >= 2;
  return false;
}

std::string Scenario::Validate() const {
  if (!town.Check()) return "town: invalid town parameters";
  if (!camera.Check()) return "camera: invalid camera (model must be perspective, unified or equirectangular, size >= 8)";
  if (!vehicle.Check()) return "vehicle: invalid vehicle parameters";
  if (!scene_file.empty() && route.type != "waypoints") return "route: a scene file needs route type waypoints";
  if (!(scene_scale > 0.0)) return "scene_scale must be > 0";
  if (!route.Check()) return "route: invalid route (type auto/loop/crossing/waypoints with enough points)";
  if (route.type == "loop" && (route.loop_i1 > town.blocks_x || route.loop_j1 > town.blocks_y)) {
    return "route: loop exceeds the town's junction grid";
  }
  if (route.type == "crossing" && (route.loop_i0 + 2 > town.blocks_x || route.loop_j0 + 2 > town.blocks_y)) {
    return "route: the crossing's 2 x 2 blocks from the loop corner exceed the town's junction grid";
  }
  if (!drive.Check()) return "drive: invalid driving parameters";
  if (!lighting.Check()) return "lighting: invalid sun or sky values";
  if (!sensor.Check()) return "sensor: exposure and gain must be > 0, noise_sigma >= 0";
  if (!render.Check()) return "render: antialiasing must be 1..8, edge_contrast >= 0 and threads >= 1";
  if (!(frame_rate > 0.0)) return "frame_rate must be > 0";
  if (num_frames < 0) return "frames must be >= 0";
  if (!markers.empty() && !(marker_radius > 0.0)) return "marker_radius must be > 0";
  return "";
}

const std::vector<LightingPreset>& LightingPresets() {
  // Lighting{sun azimuth, sun elevation, sun irradiance, sky irradiance}; the exposure keeps a sunlit facade of the
  // scenario's default light (0.75) near its grey level where there is sun, and leaves dusk dim.
  static const std::vector<LightingPreset> presets = {
      {"noon", "sun high in the south, 62 deg, short hard shadows", {180.0, 62.0, 1.5, 0.5}, 0.75},
      {"low-sun", "sun low in the west, 8 deg, long shadows across the streets", {250.0, 8.0, 1.3, 0.45}, 0.9},
      {"dusk", "sun below the horizon, dim sky light only, no shadows", {250.0, -4.0, 0.0, 0.12}, 1.2},
      {"overcast", "no direct sun, bright uniform sky, no shadows", {160.0, 0.0, 0.0, 1.0}, 0.75},
  };
  return presets;
}

const LightingPreset* FindLightingPreset(const std::string& name) {
  for (const LightingPreset& preset : LightingPresets()) {
    if (name == preset.name) return &preset;
  }
  return nullptr;
}

std::string ScenarioOverrides::Apply(Scenario* scenario) const {
  if (frames && *frames < 0) return fmt::format("--frames: must be >= 0, got {}", *frames);
  if (width && *width < 8) return fmt::format("--width: must be >= 8 pixels, got {}", *width);
  if (height && *height < 8) return fmt::format("--height: must be >= 8 pixels, got {}", *height);
  if (seed && *seed < 0) return fmt::format("--seed: must be >= 0, got {}", *seed);
  if (route && *route != "auto" && *route != "loop" && *route != "crossing") {
    return fmt::format("--route: unknown route '{}' (auto, loop or crossing)", *route);
  }
  if (segments && *segments < 1) return fmt::format("--segments: must be >= 1, got {}", *segments);
  if (max_speed && !(*max_speed > 0.0 && *max_speed <= 50.0)) {
    return fmt::format("--speed: must be in (0, 50] m/s, got {}", *max_speed);
  }
  if (frame_rate && !(*frame_rate > 0.0 && *frame_rate <= 1000.0)) {
    return fmt::format("--frame-rate: must be in (0, 1000] Hz, got {}", *frame_rate);
  }
  if (pedestrians && *pedestrians < 0) return fmt::format("--pedestrians: must be >= 0, got {}", *pedestrians);
  if (lateral_offset && !(std::abs(*lateral_offset) <= 10.0)) {
    return fmt::format("--lateral-offset: must be within +-10 m, got {}", *lateral_offset);
  }
  const LightingPreset* teach_light = lighting ? FindLightingPreset(*lighting) : nullptr;
  if (lighting && teach_light == nullptr) {
    return fmt::format("--lighting: unknown lighting '{}' (noon, low-sun, dusk or overcast)", *lighting);
  }
  const LightingPreset* repeat_light = repeat_lighting ? FindLightingPreset(*repeat_lighting) : nullptr;
  if (repeat_lighting && repeat_light == nullptr) {
    return fmt::format("--repeat-lighting: unknown lighting '{}' (noon, low-sun, dusk or overcast)", *repeat_lighting);
  }

  Scenario& s = *scenario;
  if (frames) s.num_frames = *frames;
  if (width) {
    if (s.camera.fx > 0.0) {  // intrinsics given in pixels scale with the width
      const double f = static_cast<double>(*width) / s.camera.width;
      s.camera.fx *= f;
      s.camera.fy *= f;
      if (s.camera.cx >= 0) s.camera.cx = (s.camera.cx + 0.5) * f - 0.5;
      if (s.camera.cy >= 0) s.camera.cy = (s.camera.cy + 0.5) * f - 0.5;
    }
    s.camera.width = *width;
  }
  if (height) s.camera.height = *height;
  if (seed) {
    s.seed = static_cast<uint64_t>(*seed);
    s.town.seed = s.seed;
    s.drive.wobble_seed = s.seed;
  }
  if (route) s.route.type = *route;
  if (segments) s.route.segments = *segments;
  if (max_speed) s.drive.max_speed = *max_speed;
  if (frame_rate) s.frame_rate = *frame_rate;
  if (pedestrians) s.town.num_pedestrians = *pedestrians;
  if (teach_light != nullptr) {
    s.lighting = teach_light->lighting;
    s.sensor.exposure = teach_light->exposure;
  }
  if (repeat_light != nullptr) {
    s.repeat.lighting = repeat_light->lighting;
    s.repeat.exposure = repeat_light->exposure;
  }
  if (lateral_offset) s.repeat.lateral_offset = *lateral_offset;
  return "";
}

Scenario ApplyVariant(const Scenario& scenario, ScenarioVariant variant) {
  Scenario out = scenario;
  if (variant == ScenarioVariant::kRepeat) {
    out.lighting = scenario.repeat.lighting;
    out.sensor.exposure = scenario.repeat.exposure;
    out.drive.lateral_offset = scenario.drive.lateral_offset + scenario.repeat.lateral_offset;
    out.drive.wobble_amplitude = scenario.repeat.wobble_amplitude;
    out.drive.wobble_seed = scenario.drive.wobble_seed + 1;
    out.time_offset = scenario.time_offset + scenario.repeat.time_offset;
    out.seed = scenario.seed;  // same world
  }
  return out;
}

}  // namespace retrace
