#include "retrace/sim/scenario.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "retrace/camera/equirectangular_camera.h"
#include "retrace/camera/unified_camera.h"

namespace retrace {

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

namespace {

// A numeric key, its range and where its value lives.
struct NumericKey {
  ScenarioKeyRange range;
  double (*value)(const Scenario&);
};

// Every numeric key with a fixed range, in the order of a scenario file (ScenarioToYaml). The ranges are what a
// plausible drive needs with room to spare; beyond them the renderer or the town would exhaust the machine (threads,
// memory) or the drive would never end. The largest town they allow (16 x 16 blocks of 100 m, 50 upper floors,
// trees every 5 m, 1000 pedestrians and cars, every parking slot taken) takes about 2 GB and 15 s to build; the
// default town 0.15 GB and 1 s.
const std::vector<NumericKey>& NumericKeys() {
  using S = const Scenario&;
  static const std::vector<NumericKey> keys = {
      {{"frames", 0, 1000000, true, false, ""}, [](S s) -> double { return s.num_frames; }},
      {{"frame_rate", 0.1, 1000, false, false, "Hz"}, [](S s) { return s.frame_rate; }},
      {{"time_offset", -1e6, 1e6, false, false, "s"}, [](S s) { return s.time_offset; }},
      {{"scene_scale", 1e-6, 1e6, false, false, ""}, [](S s) { return s.scene_scale; }},
      {{"marker_radius", 0.001, 100, false, false, "m"}, [](S s) { return s.marker_radius; }},
      {{"marker_brightness", 0, 100, false, false, ""}, [](S s) { return s.marker_brightness; }},
      {{"town.blocks_x", 1, 16, true, false, ""}, [](S s) -> double { return s.town.blocks_x; }},
      {{"town.blocks_y", 1, 16, true, false, ""}, [](S s) -> double { return s.town.blocks_y; }},
      {{"town.block_size_min", 10, 100, false, false, "m"}, [](S s) { return s.town.block_size_min; }},
      {{"town.block_size_max", 10, 100, false, false, "m"}, [](S s) { return s.town.block_size_max; }},
      {{"town.road_width", 3, 40, false, false, "m"}, [](S s) { return s.town.road_width; }},
      {{"town.sidewalk_width", 0.5, 10, false, false, "m"}, [](S s) { return s.town.sidewalk_width; }},
      {{"town.sidewalk_height", 0, 1, false, false, "m"}, [](S s) { return s.town.sidewalk_height; }},
      {{"town.park_probability", 0, 1, false, false, ""}, [](S s) { return s.town.park_probability; }},
      {{"town.min_upper_floors", 0, 50, true, false, ""}, [](S s) -> double { return s.town.min_upper_floors; }},
      {{"town.max_upper_floors", 0, 50, true, false, ""}, [](S s) -> double { return s.town.max_upper_floors; }},
      {{"town.tree_spacing", 5, 1000, false, true, "m"}, [](S s) { return s.town.tree_spacing; }},
      {{"town.parked_car_probability", 0, 1, false, false, ""}, [](S s) { return s.town.parked_car_probability; }},
      {{"town.pedestrians", 0, 1000, true, false, ""}, [](S s) -> double { return s.town.num_pedestrians; }},
      {{"town.moving_cars", 0, 1000, true, false, ""}, [](S s) -> double { return s.town.num_moving_cars; }},
      {{"camera.width", 8, 8192, true, false, "pixels"}, [](S s) -> double { return s.camera.width; }},
      {{"camera.height", 8, 8192, true, false, "pixels"}, [](S s) -> double { return s.camera.height; }},
      {{"camera.hfov_deg", 1, 360, false, false, "degrees"}, [](S s) { return s.camera.hfov_deg; }},
      {{"camera.xi", 0, 10, false, false, ""}, [](S s) { return s.camera.xi; }},
      {{"camera.fx", 1, 1e6, false, true, "pixels"}, [](S s) { return s.camera.fx; }},
      {{"camera.fy", 1, 1e6, false, true, "pixels"}, [](S s) { return s.camera.fy; }},
      {{"camera.distortion.k1", -100, 100, false, false, ""}, [](S s) { return s.camera.distortion.k1; }},
      {{"camera.distortion.k2", -100, 100, false, false, ""}, [](S s) { return s.camera.distortion.k2; }},
      {{"camera.distortion.k3", -100, 100, false, false, ""}, [](S s) { return s.camera.distortion.k3; }},
      {{"camera.distortion.p1", -1, 1, false, false, ""}, [](S s) { return s.camera.distortion.p1; }},
      {{"camera.distortion.p2", -1, 1, false, false, ""}, [](S s) { return s.camera.distortion.p2; }},
      {{"vehicle.wheelbase", 0.5, 20, false, false, "m"}, [](S s) { return s.vehicle.wheelbase; }},
      {{"vehicle.max_steering_deg", 1, 79, false, false, "degrees"}, [](S s) { return s.vehicle.max_steering_deg; }},
      {{"vehicle.camera_height", 0.1, 50, false, false, "m"}, [](S s) { return s.vehicle.camera_height; }},
      {{"vehicle.camera_forward", -20, 20, false, false, "m"}, [](S s) { return s.vehicle.camera_forward; }},
      {{"vehicle.camera_tilt_deg", -88, 88, false, false, "degrees"}, [](S s) { return s.vehicle.camera_tilt_deg; }},
      {{"vehicle.escorts", 0, kMaxEscorts, true, false, ""}, [](S s) -> double { return s.vehicle.escorts; }},
      {{"route.segments", 1, 1000, true, false, ""}, [](S s) -> double { return s.route.segments; }},
      {{"drive.max_speed", 0.5, 50, false, false, "m/s"}, [](S s) { return s.drive.max_speed; }},
      {{"drive.max_lateral_acceleration", 0.1, 20, false, false, "m/s^2"},
       [](S s) { return s.drive.max_lateral_acceleration; }},
      {{"drive.max_acceleration", 0.1, 20, false, false, "m/s^2"}, [](S s) { return s.drive.max_acceleration; }},
      {{"drive.max_deceleration", 0.1, 20, false, false, "m/s^2"}, [](S s) { return s.drive.max_deceleration; }},
      {{"drive.corner_radius", 0, 100, false, false, "m"}, [](S s) { return s.drive.corner_radius; }},
      {{"drive.lateral_offset", -10, 10, false, false, "m"}, [](S s) { return s.drive.lateral_offset; }},
      {{"drive.wobble_amplitude", 0, 5, false, false, "m"}, [](S s) { return s.drive.wobble_amplitude; }},
      {{"drive.wobble_wavelength", 1, 10000, false, false, "m"}, [](S s) { return s.drive.wobble_wavelength; }},
      {{"lighting.sun_azimuth_deg", -360, 360, false, false, "degrees"},
       [](S s) { return s.lighting.sun_azimuth_deg; }},
      {{"lighting.sun_elevation_deg", -90, 90, false, false, "degrees"},
       [](S s) { return s.lighting.sun_elevation_deg; }},
      {{"lighting.sun_irradiance", 0, 100, false, false, ""}, [](S s) { return s.lighting.sun_irradiance; }},
      {{"lighting.sky_irradiance", 0, 100, false, false, ""}, [](S s) { return s.lighting.sky_irradiance; }},
      {{"sensor.exposure", 0.001, 100, false, false, ""}, [](S s) { return s.sensor.exposure; }},
      {{"sensor.gain", 0.001, 100, false, false, ""}, [](S s) { return s.sensor.gain; }},
      {{"sensor.noise_sigma", 0, 100, false, false, "grey levels"}, [](S s) { return s.sensor.noise_sigma; }},
      {{"render.antialiasing", 1, 8, true, false, ""}, [](S s) -> double { return s.render.antialiasing; }},
      {{"render.edge_contrast", 0, 255, false, false, "grey levels"}, [](S s) { return s.render.edge_contrast; }},
      {{"render.threads", 1, 256, true, false, ""}, [](S s) -> double { return s.render.num_threads; }},
      {{"repeat.sun_azimuth_deg", -360, 360, false, false, "degrees"},
       [](S s) { return s.repeat.lighting.sun_azimuth_deg; }},
      {{"repeat.sun_elevation_deg", -90, 90, false, false, "degrees"},
       [](S s) { return s.repeat.lighting.sun_elevation_deg; }},
      {{"repeat.sun_irradiance", 0, 100, false, false, ""}, [](S s) { return s.repeat.lighting.sun_irradiance; }},
      {{"repeat.sky_irradiance", 0, 100, false, false, ""}, [](S s) { return s.repeat.lighting.sky_irradiance; }},
      {{"repeat.exposure", 0.001, 100, false, false, ""}, [](S s) { return s.repeat.exposure; }},
      {{"repeat.lateral_offset", -10, 10, false, false, "m"}, [](S s) { return s.repeat.lateral_offset; }},
      {{"repeat.wobble_amplitude", 0, 5, false, false, "m"}, [](S s) { return s.repeat.wobble_amplitude; }},
      {{"repeat.time_offset", -1e6, 1e6, false, false, "s"}, [](S s) { return s.repeat.time_offset; }},
  };
  return keys;
}

// A number as the messages show it: integers without a decimal point, others in the shortest form.
std::string Number(double value) { return fmt::format("{}", value); }

ScenarioProblem OutOfRange(const ScenarioKeyRange& range, double value) {
  return {range.key, fmt::format("must be {}, got {}", range.Text(), Number(value))};
}

// Length of a polyline (metres).
double PolylineLength(const std::vector<Vector2d>& points) {
  double length = 0.0;
  for (size_t i = 1; i < points.size(); ++i) length += (points[i] - points[i - 1]).norm();
  return length;
}

}  // namespace

std::string ScenarioKeyRange::Text() const {
  const std::string unit_text = unit[0] == '\0' ? "" : std::string(" ") + unit;
  const std::string interval = integer ? fmt::format("in {}..{}", Number(min), Number(max))
                                       : fmt::format("in [{}, {}]", Number(min), Number(max));
  return (zero_allowed ? "0 or " : "") + interval + unit_text;
}

bool ScenarioKeyRange::Contains(double value) const {
  if (zero_allowed && value == 0.0) return true;
  return value >= min && value <= max && (!integer || value == std::floor(value));
}

const std::vector<ScenarioKeyRange>& ScenarioKeyRanges() {
  static const std::vector<ScenarioKeyRange> ranges = [] {
    std::vector<ScenarioKeyRange> out;
    for (const NumericKey& key : NumericKeys()) out.push_back(key.range);
    return out;
  }();
  return ranges;
}

const ScenarioKeyRange* FindScenarioKeyRange(const std::string& key) {
  for (const ScenarioKeyRange& range : ScenarioKeyRanges()) {
    if (key == range.key) return &range;
  }
  return nullptr;
}

std::optional<ScenarioProblem> Scenario::Check() const {
  for (const NumericKey& key : NumericKeys()) {
    const double value = key.value(*this);
    if (!key.range.Contains(value)) return OutOfRange(key.range, value);
  }
  // Rules that tie keys together. The repeat variant (ApplyVariant) adds its offsets to the teach drive's: the sums
  // have the ranges of the teach drive's keys.
  const ScenarioKeyRange& offset = *FindScenarioKeyRange("drive.lateral_offset");
  if (!offset.Contains(drive.lateral_offset + repeat.lateral_offset)) {
    return ScenarioProblem{"repeat.lateral_offset",
                           fmt::format("the repeat drive's offset drive.lateral_offset + repeat.lateral_offset must be "
                                       "{}, got {}",
                                       offset.Text(), Number(drive.lateral_offset + repeat.lateral_offset))};
  }
  const ScenarioKeyRange& clock = *FindScenarioKeyRange("time_offset");
  if (!clock.Contains(time_offset + repeat.time_offset)) {
    return ScenarioProblem{"repeat.time_offset",
                           fmt::format("the repeat drive's clock time_offset + repeat.time_offset must be {}, got {}",
                                       clock.Text(), Number(time_offset + repeat.time_offset))};
  }
  if (town.block_size_max < town.block_size_min) {
    return ScenarioProblem{"town.block_size_max",
                           fmt::format("must be >= town.block_size_min ({}), got {}", Number(town.block_size_min),
                                       Number(town.block_size_max))};
  }
  if (town.max_upper_floors < town.min_upper_floors) {
    return ScenarioProblem{"town.max_upper_floors",
                           fmt::format("must be >= town.min_upper_floors ({}), got {}", town.min_upper_floors,
                                       town.max_upper_floors)};
  }
  const double samples = static_cast<double>(camera.width) * camera.height *
                         std::max(4, render.antialiasing * render.antialiasing);
  if (samples > kMaxRenderSamples) {
    return ScenarioProblem{
        "camera.width",
        fmt::format("{} x {} pixels at render.antialiasing {} exceed the renderer's memory budget: width x height x "
                    "max(4, antialiasing^2) must be <= {} (e.g. 4096 x 4096 up to antialiasing 2), got {}",
                    camera.width, camera.height, render.antialiasing, Number(kMaxRenderSamples), Number(samples))};
  }
  if (camera.model == "perspective" && camera.fx == 0.0 && !(camera.hfov_deg <= 179.0)) {
    return ScenarioProblem{"camera.hfov_deg",
                           fmt::format("must be in [1, 179] degrees for a perspective camera, got {}",
                                       Number(camera.hfov_deg))};
  }
  if (camera.model == "unified" && camera.fx == 0.0 &&
      !(std::cos(0.5 * camera.hfov_deg * M_PI / 180.0) + camera.xi > 0.05)) {
    return ScenarioProblem{"camera.hfov_deg",
                           fmt::format("{} degrees is beyond what a unified camera with xi = {} sees (cos(hfov / 2) + "
                                       "xi must be > 0.05)",
                                       Number(camera.hfov_deg), Number(camera.xi))};
  }
  const auto principal_point = [](const char* key, double value, int size) -> std::optional<ScenarioProblem> {
    if (std::isfinite(value) && value <= size) return std::nullopt;
    return ScenarioProblem{key, fmt::format("must be negative (the image centre) or in [0, {}] pixels, got {}", size,
                                            Number(value))};
  };
  if (auto problem = principal_point("camera.cx", camera.cx, camera.width)) return problem;
  if (auto problem = principal_point("camera.cy", camera.cy, camera.height)) return problem;
  if (camera.model != "perspective" && camera.model != "unified" && camera.model != "equirectangular") {
    return ScenarioProblem{"camera.model",
                           fmt::format("must be perspective, unified or equirectangular, got '{}'", camera.model)};
  }

  if (!scene_file.empty() && route.type != "waypoints") {
    return ScenarioProblem{"route.type", "a scene file needs route type waypoints, got '" + route.type + "'"};
  }
  if (route.type == "loop" &&
      !(route.loop_i0 >= 0 && route.loop_j0 >= 0 && route.loop_i1 > route.loop_i0 && route.loop_j1 > route.loop_j0 &&
        route.loop_i1 <= town.blocks_x && route.loop_j1 <= town.blocks_y)) {
    return ScenarioProblem{"route.loop", fmt::format("[i0, j0, i1, j1] must have 0 <= i0 < i1 <= town.blocks_x ({}) "
                                                     "and 0 <= j0 < j1 <= town.blocks_y ({}), got [{}, {}, {}, {}]",
                                                     town.blocks_x, town.blocks_y, route.loop_i0, route.loop_j0,
                                                     route.loop_i1, route.loop_j1)};
  }
  if (route.type == "crossing" && !(route.loop_i0 >= 0 && route.loop_j0 >= 0 &&
                                    route.loop_i0 + 2 <= town.blocks_x && route.loop_j0 + 2 <= town.blocks_y)) {
    return ScenarioProblem{"route.loop",
                           fmt::format("the crossing's 2 x 2 blocks from [i0, j0] = [{}, {}] exceed the town's "
                                       "junction grid: 0 <= i0 <= town.blocks_x - 2 ({}) and 0 <= j0 <= "
                                       "town.blocks_y - 2 ({})",
                                       route.loop_i0, route.loop_j0, town.blocks_x - 2, town.blocks_y - 2)};
  }
  if (route.type == "waypoints") {
    if (route.waypoints.size() < 2 || route.waypoints.size() > static_cast<size_t>(kMaxWaypoints)) {
      return ScenarioProblem{"route.waypoints", fmt::format("a waypoints route needs 2..{} points, got {}",
                                                            kMaxWaypoints, route.waypoints.size())};
    }
    for (size_t i = 0; i < route.waypoints.size(); ++i) {
      if (!(route.waypoints[i].cwiseAbs().maxCoeff() <= kMaxCoordinate)) {
        return ScenarioProblem{fmt::format("route.waypoints[{}]", i),
                               fmt::format("coordinates must be within +-{} m, got [{}, {}]", Number(kMaxCoordinate),
                                           Number(route.waypoints[i].x()), Number(route.waypoints[i].y()))};
      }
    }
    const double length = PolylineLength(route.waypoints);
    if (!(length >= 1.0 && length <= kMaxRouteLength)) {
      return ScenarioProblem{"route.waypoints", fmt::format("the route must be 1..{} m long, got {:.1f} m",
                                                            Number(kMaxRouteLength), length)};
    }
  } else if (route.type == "junctions") {
    if (route.junctions.size() < 2 || route.junctions.size() > static_cast<size_t>(kMaxWaypoints)) {
      return ScenarioProblem{"route.junctions", fmt::format("a junctions route needs 2..{} junctions, got {}",
                                                            kMaxWaypoints, route.junctions.size())};
    }
    for (size_t k = 0; k < route.junctions.size(); ++k) {
      const auto [i, j] = route.junctions[k];
      if (!(i >= 0 && j >= 0 && i <= town.blocks_x && j <= town.blocks_y)) {
        return ScenarioProblem{fmt::format("route.junctions[{}]", k),
                               fmt::format("[i, j] must have 0 <= i <= town.blocks_x ({}) and 0 <= j <= "
                                           "town.blocks_y ({}), got [{}, {}]",
                                           town.blocks_x, town.blocks_y, i, j)};
      }
      if (k > 0) {
        const auto [pi, pj] = route.junctions[k - 1];
        if ((pi == i) == (pj == j)) {
          return ScenarioProblem{fmt::format("route.junctions[{}]", k),
                                 fmt::format("[{}, {}] is not along one street from [{}, {}] (one index must stay)",
                                             i, j, pi, pj)};
        }
      }
    }
  } else if (route.type != "auto" && route.type != "loop" && route.type != "crossing") {
    return ScenarioProblem{"route.type",
                           "must be auto, loop, crossing, junctions or waypoints, got '" + route.type + "'"};
  }
  if (markers.size() > static_cast<size_t>(kMaxMarkers)) {
    return ScenarioProblem{"markers", fmt::format("at most {} markers, got {}", kMaxMarkers, markers.size())};
  }
  for (size_t i = 0; i < markers.size(); ++i) {
    if (!(markers[i].cwiseAbs().maxCoeff() <= kMaxCoordinate)) {
      return ScenarioProblem{fmt::format("markers[{}]", i),
                             fmt::format("coordinates must be within +-{} m, got [{}, {}, {}]", Number(kMaxCoordinate),
                                         Number(markers[i].x()), Number(markers[i].y()), Number(markers[i].z()))};
    }
  }
  return std::nullopt;
}

std::string Scenario::Validate() const {
  const std::optional<ScenarioProblem> problem = Check();
  return problem ? problem->ToString() : "";
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
  // Names first (they are not numbers with a range), then the numbers through Scenario::Check.
  if (seed && *seed < 0) {
    return fmt::format("--seed: must be in 0..{}, got {}", std::numeric_limits<int64_t>::max(), *seed);
  }
  if (route && *route != "auto" && *route != "loop" && *route != "crossing") {
    return fmt::format("--route: unknown route '{}' (auto, loop or crossing)", *route);
  }
  const LightingPreset* teach_light = lighting ? FindLightingPreset(*lighting) : nullptr;
  if (lighting && teach_light == nullptr) {
    return fmt::format("--lighting: unknown lighting '{}' (noon, low-sun, dusk or overcast)", *lighting);
  }
  const LightingPreset* repeat_light = repeat_lighting ? FindLightingPreset(*repeat_lighting) : nullptr;
  if (repeat_lighting && repeat_light == nullptr) {
    return fmt::format("--repeat-lighting: unknown lighting '{}' (noon, low-sun, dusk or overcast)", *repeat_lighting);
  }

  Scenario s = *scenario;
  if (frames) s.num_frames = *frames;
  if (width) {
    if (s.camera.fx > 0.0 && *width > 0) {  // intrinsics given in pixels scale with the width
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
  if (threads) s.render.num_threads = *threads;

  if (const std::optional<ScenarioProblem> problem = s.Check()) {
    // The option that set the key at fault, if one did.
    struct OptionOfKey {
      const char* key;
      const char* option;
      bool given;
    };
    const OptionOfKey options[] = {
        {"frames", "--frames", frames.has_value()},
        {"camera.width", "--width", width.has_value()},
        {"camera.height", "--height", height.has_value()},
        {"route.segments", "--segments", segments.has_value()},
        {"drive.max_speed", "--speed", max_speed.has_value()},
        {"frame_rate", "--frame-rate", frame_rate.has_value()},
        {"town.pedestrians", "--pedestrians", pedestrians.has_value()},
        {"repeat.lateral_offset", "--lateral-offset", lateral_offset.has_value()},
        {"render.threads", "--threads", threads.has_value()},
    };
    for (const OptionOfKey& o : options) {
      if (o.given && problem->key == o.key) return std::string(o.option) + ": " + problem->message;
    }
    return problem->ToString();
  }
  *scenario = s;
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
