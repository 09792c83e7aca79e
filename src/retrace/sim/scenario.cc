#include "retrace/sim/scenario.h"

#include <cmath>

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
  if (type == "waypoints") return waypoints.size() >= 2;
  return false;
}

std::string Scenario::Validate() const {
  if (!town.Check()) return "town: invalid town parameters";
  if (!camera.Check()) return "camera: invalid camera (model must be perspective, unified or equirectangular, size >= 8)";
  if (!vehicle.Check()) return "vehicle: invalid vehicle parameters";
  if (!scene_file.empty() && route.type != "waypoints") return "route: a scene file needs route type waypoints";
  if (!(scene_scale > 0.0)) return "scene_scale must be > 0";
  if (!route.Check()) return "route: invalid route (type auto/loop/waypoints with enough points)";
  if (route.type == "loop" && (route.loop_i1 > town.blocks_x || route.loop_j1 > town.blocks_y)) {
    return "route: loop exceeds the town's junction grid";
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
