#include "retrace/sim/scenario_io.h"

#include <fstream>
#include <optional>
#include <set>
#include <sstream>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include "retrace/util/error.h"

namespace retrace {
namespace {

class Reader {
 public:
  explicit Reader(std::string source) : source_(std::move(source)) {}

  [[noreturn]] void Fail(const YAML::Node& node, const std::string& key, const std::string& problem) const {
    const int line = node.Mark().line >= 0 ? node.Mark().line + 1 : 0;
    throw InputError(source_, fmt::format("line {}: {}: {}", line, key, problem));
  }

  // Checks that `node` is a map whose keys are all in `allowed`.
  void CheckMap(const YAML::Node& node, const std::string& path, const std::set<std::string>& allowed) const {
    if (!node.IsMap()) Fail(node, path.empty() ? "(top level)" : path, "expected a map of keys");
    for (const auto& entry : node) {
      const std::string key = entry.first.as<std::string>();
      if (!allowed.count(key)) {
        Fail(entry.first, path.empty() ? key : path + "." + key, "unknown key");
      }
    }
  }

  template <typename T>
  void Get(const YAML::Node& map, const std::string& path, const char* key, T* value, const char* type) const {
    const YAML::Node node = map[key];
    if (!node) return;
    const std::string name = path.empty() ? key : path + "." + key;
    if (!node.IsScalar()) Fail(node, name, fmt::format("expected {}", type));
    try {
      *value = node.as<T>();
    } catch (const YAML::Exception&) {
      Fail(node, name, fmt::format("expected {}, got '{}'", type, node.Scalar()));
    }
  }
  void Number(const YAML::Node& m, const std::string& p, const char* k, double* v) const { Get(m, p, k, v, "a number"); }
  void Integer(const YAML::Node& m, const std::string& p, const char* k, int* v) const { Get(m, p, k, v, "an integer"); }
  void Seed(const YAML::Node& m, const std::string& p, const char* k, uint64_t* v) const {
    Get(m, p, k, v, "a non-negative integer");
  }
  void Bool(const YAML::Node& m, const std::string& p, const char* k, bool* v) const { Get(m, p, k, v, "true or false"); }
  void String(const YAML::Node& m, const std::string& p, const char* k, std::string* v) const {
    Get(m, p, k, v, "a string");
  }

  const std::string& source() const { return source_; }

 private:
  std::string source_;
};

Scenario ParseNode(const YAML::Node& root, const Reader& r) {
  Scenario s;
  if (!root || root.IsNull()) return s;
  r.CheckMap(root, "", {"seed", "frames", "scene_file", "scene_scale", "scene_y_up", "frame_rate", "time_offset", "markers", "marker_radius",
                        "marker_brightness", "town", "camera", "vehicle", "route", "drive",
                        "lighting", "sensor", "render", "repeat"});
  r.Seed(root, "", "seed", &s.seed);
  s.town.seed = s.seed;
  s.drive.wobble_seed = s.seed;
  r.Integer(root, "", "frames", &s.num_frames);
  r.Number(root, "", "frame_rate", &s.frame_rate);
  r.Number(root, "", "time_offset", &s.time_offset);
  r.String(root, "", "scene_file", &s.scene_file);
  r.Number(root, "", "scene_scale", &s.scene_scale);
  r.Bool(root, "", "scene_y_up", &s.scene_y_up);
  r.Number(root, "", "marker_radius", &s.marker_radius);
  r.Number(root, "", "marker_brightness", &s.marker_brightness);
  if (const YAML::Node m = root["markers"]) {
    if (!m.IsSequence()) r.Fail(m, "markers", "expected a list of [x, y, z] points");
    for (size_t i = 0; i < m.size(); ++i) {
      const YAML::Node p = m[i];
      if (!p.IsSequence() || p.size() != 3) r.Fail(p, fmt::format("markers[{}]", i), "expected [x, y, z]");
      try {
        s.markers.emplace_back(p[0].as<double>(), p[1].as<double>(), p[2].as<double>());
      } catch (const YAML::Exception&) {
        r.Fail(p, fmt::format("markers[{}]", i), "expected three numbers [x, y, z]");
      }
    }
  }
  if (const YAML::Node n = root["town"]) {
    r.CheckMap(n, "town", {"seed", "blocks_x", "blocks_y", "block_size_min", "block_size_max", "road_width",
                           "sidewalk_width", "sidewalk_height", "park_probability", "min_upper_floors",
                           "max_upper_floors", "tree_spacing", "parked_car_probability", "pedestrians", "moving_cars",
                           "photo_folder"});
    TownOptions& t = s.town;
    r.Seed(n, "town", "seed", &t.seed);
    r.Integer(n, "town", "blocks_x", &t.blocks_x);
    r.Integer(n, "town", "blocks_y", &t.blocks_y);
    r.Number(n, "town", "block_size_min", &t.block_size_min);
    r.Number(n, "town", "block_size_max", &t.block_size_max);
    r.Number(n, "town", "road_width", &t.road_width);
    r.Number(n, "town", "sidewalk_width", &t.sidewalk_width);
    r.Number(n, "town", "sidewalk_height", &t.sidewalk_height);
    r.Number(n, "town", "park_probability", &t.park_probability);
    r.Integer(n, "town", "min_upper_floors", &t.min_upper_floors);
    r.Integer(n, "town", "max_upper_floors", &t.max_upper_floors);
    r.Number(n, "town", "tree_spacing", &t.tree_spacing);
    r.Number(n, "town", "parked_car_probability", &t.parked_car_probability);
    r.Integer(n, "town", "pedestrians", &t.num_pedestrians);
    r.Integer(n, "town", "moving_cars", &t.num_moving_cars);
    r.String(n, "town", "photo_folder", &t.photo_folder);
  }
  if (const YAML::Node n = root["camera"]) {
    r.CheckMap(n, "camera", {"model", "width", "height", "hfov_deg", "xi", "fx", "fy", "cx", "cy", "distortion"});
    CameraSpec& c = s.camera;
    r.String(n, "camera", "model", &c.model);
    if (c.model != "perspective" && c.model != "unified" && c.model != "equirectangular") {
      r.Fail(n["model"], "camera.model", "expected perspective, unified or equirectangular, got '" + c.model + "'");
    }
    r.Integer(n, "camera", "width", &c.width);
    r.Integer(n, "camera", "height", &c.height);
    r.Number(n, "camera", "hfov_deg", &c.hfov_deg);
    r.Number(n, "camera", "xi", &c.xi);
    r.Number(n, "camera", "fx", &c.fx);
    r.Number(n, "camera", "fy", &c.fy);
    r.Number(n, "camera", "cx", &c.cx);
    r.Number(n, "camera", "cy", &c.cy);
    if (const YAML::Node d = n["distortion"]) {
      r.CheckMap(d, "camera.distortion", {"k1", "k2", "k3", "p1", "p2"});
      r.Number(d, "camera.distortion", "k1", &c.distortion.k1);
      r.Number(d, "camera.distortion", "k2", &c.distortion.k2);
      r.Number(d, "camera.distortion", "k3", &c.distortion.k3);
      r.Number(d, "camera.distortion", "p1", &c.distortion.p1);
      r.Number(d, "camera.distortion", "p2", &c.distortion.p2);
    }
  }
  if (const YAML::Node n = root["vehicle"]) {
    r.CheckMap(n, "vehicle",
               {"wheelbase", "max_steering_deg", "camera_height", "camera_forward", "camera_tilt_deg", "escorts"});
    r.Number(n, "vehicle", "wheelbase", &s.vehicle.wheelbase);
    r.Number(n, "vehicle", "max_steering_deg", &s.vehicle.max_steering_deg);
    r.Number(n, "vehicle", "camera_height", &s.vehicle.camera_height);
    r.Number(n, "vehicle", "camera_forward", &s.vehicle.camera_forward);
    r.Number(n, "vehicle", "camera_tilt_deg", &s.vehicle.camera_tilt_deg);
    r.Integer(n, "vehicle", "escorts", &s.vehicle.escorts);
  }
  if (const YAML::Node n = root["route"]) {
    r.CheckMap(n, "route", {"type", "segments", "loop", "waypoints", "junctions"});
    r.String(n, "route", "type", &s.route.type);
    if (s.route.type != "auto" && s.route.type != "loop" && s.route.type != "crossing" &&
        s.route.type != "junctions" && s.route.type != "waypoints") {
      r.Fail(n["type"], "route.type",
             "expected auto, loop, crossing, junctions or waypoints, got '" + s.route.type + "'");
    }
    if (const YAML::Node w = n["junctions"]) {
      if (!w.IsSequence()) r.Fail(w, "route.junctions", "expected a list of [i, j] junction indices");
      s.route.junctions.clear();
      for (size_t k = 0; k < w.size(); ++k) {
        const YAML::Node p = w[k];
        if (!p.IsSequence() || p.size() != 2) r.Fail(p, fmt::format("route.junctions[{}]", k), "expected [i, j]");
        try {
          s.route.junctions.push_back({p[0].as<int>(), p[1].as<int>()});
        } catch (const YAML::Exception&) {
          r.Fail(p, fmt::format("route.junctions[{}]", k), "expected two integers [i, j]");
        }
      }
    }
    r.Integer(n, "route", "segments", &s.route.segments);
    if (const YAML::Node l = n["loop"]) {
      if (!l.IsSequence() || l.size() != 4) r.Fail(l, "route.loop", "expected [i0, j0, i1, j1]");
      try {
        s.route.loop_i0 = l[0].as<int>();
        s.route.loop_j0 = l[1].as<int>();
        s.route.loop_i1 = l[2].as<int>();
        s.route.loop_j1 = l[3].as<int>();
      } catch (const YAML::Exception&) {
        r.Fail(l, "route.loop", "expected four integers [i0, j0, i1, j1]");
      }
    }
    if (const YAML::Node w = n["waypoints"]) {
      if (!w.IsSequence()) r.Fail(w, "route.waypoints", "expected a list of [x, y] points");
      s.route.waypoints.clear();
      for (size_t i = 0; i < w.size(); ++i) {
        const YAML::Node p = w[i];
        if (!p.IsSequence() || p.size() != 2) r.Fail(p, fmt::format("route.waypoints[{}]", i), "expected [x, y]");
        try {
          s.route.waypoints.emplace_back(p[0].as<double>(), p[1].as<double>());
        } catch (const YAML::Exception&) {
          r.Fail(p, fmt::format("route.waypoints[{}]", i), "expected two numbers [x, y]");
        }
      }
    }
  }
  if (const YAML::Node n = root["drive"]) {
    r.CheckMap(n, "drive", {"max_speed", "max_lateral_acceleration", "max_acceleration", "max_deceleration",
                            "corner_radius", "start_at_rest", "lateral_offset", "wobble_amplitude",
                            "wobble_wavelength", "wobble_seed"});
    DriveOptions& d = s.drive;
    r.Number(n, "drive", "max_speed", &d.max_speed);
    r.Number(n, "drive", "max_lateral_acceleration", &d.max_lateral_acceleration);
    r.Number(n, "drive", "max_acceleration", &d.max_acceleration);
    r.Number(n, "drive", "max_deceleration", &d.max_deceleration);
    r.Number(n, "drive", "corner_radius", &d.corner_radius);
    r.Bool(n, "drive", "start_at_rest", &d.start_at_rest);
    r.Number(n, "drive", "lateral_offset", &d.lateral_offset);
    r.Number(n, "drive", "wobble_amplitude", &d.wobble_amplitude);
    r.Number(n, "drive", "wobble_wavelength", &d.wobble_wavelength);
    r.Seed(n, "drive", "wobble_seed", &d.wobble_seed);
  }
  auto read_lighting = [&](const YAML::Node& n, const std::string& path, Lighting* l) {
    r.Number(n, path, "sun_azimuth_deg", &l->sun_azimuth_deg);
    r.Number(n, path, "sun_elevation_deg", &l->sun_elevation_deg);
    r.Number(n, path, "sun_irradiance", &l->sun_irradiance);
    r.Number(n, path, "sky_irradiance", &l->sky_irradiance);
  };
  if (const YAML::Node n = root["lighting"]) {
    r.CheckMap(n, "lighting", {"sun_azimuth_deg", "sun_elevation_deg", "sun_irradiance", "sky_irradiance"});
    read_lighting(n, "lighting", &s.lighting);
  }
  if (const YAML::Node n = root["sensor"]) {
    r.CheckMap(n, "sensor", {"exposure", "gain", "noise_sigma", "color"});
    r.Number(n, "sensor", "exposure", &s.sensor.exposure);
    r.Number(n, "sensor", "gain", &s.sensor.gain);
    r.Number(n, "sensor", "noise_sigma", &s.sensor.noise_sigma);
    r.Bool(n, "sensor", "color", &s.sensor.color);
  }
  if (const YAML::Node n = root["render"]) {
    r.CheckMap(n, "render", {"antialiasing", "edge_contrast", "filter_textures", "shadows", "threads"});
    r.Integer(n, "render", "antialiasing", &s.render.antialiasing);
    r.Number(n, "render", "edge_contrast", &s.render.edge_contrast);
    r.Bool(n, "render", "filter_textures", &s.render.filter_textures);
    r.Bool(n, "render", "shadows", &s.render.shadows);
    r.Integer(n, "render", "threads", &s.render.num_threads);
  }
  if (const YAML::Node n = root["repeat"]) {
    r.CheckMap(n, "repeat", {"sun_azimuth_deg", "sun_elevation_deg", "sun_irradiance", "sky_irradiance", "exposure",
                             "lateral_offset", "wobble_amplitude", "time_offset"});
    read_lighting(n, "repeat", &s.repeat.lighting);
    r.Number(n, "repeat", "exposure", &s.repeat.exposure);
    r.Number(n, "repeat", "lateral_offset", &s.repeat.lateral_offset);
    r.Number(n, "repeat", "wobble_amplitude", &s.repeat.wobble_amplitude);
    r.Number(n, "repeat", "time_offset", &s.repeat.time_offset);
  }
  if (const std::optional<ScenarioProblem> problem = s.Check()) {
    // Name the line of the key at fault when the file sets it ("route.waypoints[3]" is on the line of
    // route.waypoints); a key left at its default is at fault only through another one, named in the message.
    YAML::Node node;
    node.reset(root);  // reset, not =: assigning to a YAML::Node writes into the node it refers to
    std::stringstream path(problem->key.substr(0, problem->key.find('[')));
    for (std::string part; std::getline(path, part, '.');) {
      const YAML::Node map = node;  // const lookups add no keys
      const YAML::Node child = map.IsMap() ? map[part] : YAML::Node();
      if (!child) throw InputError(r.source(), problem->ToString());
      node.reset(child);
    }
    r.Fail(node, problem->key, problem->message);
  }
  return s;
}

}  // namespace

Scenario ParseScenario(const std::string& text, const std::string& source) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    throw InputError(source, fmt::format("line {}: syntax error: {}", e.mark.line + 1, e.msg));
  }
  return ParseNode(root, Reader(source));
}

Scenario ReadScenario(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path.string(), "cannot open the scenario file");
  std::stringstream buffer;
  buffer << in.rdbuf();
  Scenario scenario = ParseScenario(buffer.str(), path.string());
  // Files named in the scenario are relative to the scenario file.
  auto resolve = [&](std::string* file) {
    if (!file->empty() && std::filesystem::path(*file).is_relative()) *file = (path.parent_path() / *file).string();
  };
  resolve(&scenario.scene_file);
  resolve(&scenario.town.photo_folder);
  return scenario;
}

namespace {

// `text` (a line of ScenarioToYaml) with the documented range of its key appended to its comment; `section` is the
// current top-level key, updated by top-level lines.
std::string WithRange(const std::string& text, std::string* section) {
  const size_t indent = text.find_first_not_of(' ');
  const size_t colon = text.find(':');
  if (indent == std::string::npos || colon == std::string::npos || text[indent] == '#') return text;
  const std::string key = text.substr(indent, colon - indent);
  if (indent == 0) *section = key;
  const ScenarioKeyRange* range = FindScenarioKeyRange(indent == 0 ? key : *section + "." + key);
  if (range == nullptr) return text;
  return text + (text.find(" # ") == std::string::npos ? "  # " : "; ") + range->Text();
}

}  // namespace

std::string ScenarioToYaml(const Scenario& s) {
  std::string o;
  std::string section;
  auto line = [&](const std::string& text) { o += WithRange(text, &section) + "\n"; };
  auto b = [](bool v) { return v ? "true" : "false"; };
  line("# retrace simulator scenario. Every key is optional; missing keys take these defaults.");
  line("# Render with: retrace sim render --scenario FILE --out DIR [--variant teach|repeat]");
  line(fmt::format("seed: {}                # seed of the drive (and of the town unless town.seed is given); seeds: "
                   "0..2^64-1",
                   s.seed));
  line(fmt::format("frames: {}              # number of frames; 0 = drive the whole route (it stops at the route's "
                   "end anyway)",
                   s.num_frames));
  line(fmt::format("frame_rate: {}         # frames per second", s.frame_rate));
  line(fmt::format("time_offset: {}         # seconds on the clock of moving pedestrians/cars at frame 0", s.time_offset));
  line(fmt::format("scene_file: \"{}\"          # your scene (glTF/OBJ/...); \"\" = the built-in town below. Needs "
                   "route type waypoints", s.scene_file));
  line(fmt::format("scene_scale: {}           # metres per scene-file unit", s.scene_scale));
  line(fmt::format("scene_y_up: {}         # the scene file's up axis is Y (glTF) rather than Z", s.scene_y_up ? "true" : "false"));
  std::string markers;
  for (const auto& p : s.markers) markers += fmt::format("{}[{}, {}, {}]", markers.empty() ? "" : ", ", p.x(), p.y(), p.z());
  line(fmt::format("markers: [{}]             # self-luminous spheres at world-frame points (x right, y down, z forward "
                   "at the route start); at most 1000, within +-100 km", markers));
  line(fmt::format("marker_radius: {}", s.marker_radius));
  line(fmt::format("marker_brightness: {}", s.marker_brightness));
  line("town:                    # the built-in procedural town (X east, Y north, Z up, metres)");
  line(fmt::format("  seed: {}", s.town.seed));
  line(fmt::format("  blocks_x: {}            # blocks west-east; junctions are numbered 0..blocks_x", s.town.blocks_x));
  line(fmt::format("  blocks_y: {}            # blocks south-north", s.town.blocks_y));
  line(fmt::format("  block_size_min: {}     # metres between sidewalks", s.town.block_size_min));
  line(fmt::format("  block_size_max: {}", s.town.block_size_max));
  line(fmt::format("  road_width: {}          # carriageway (two lanes), metres", s.town.road_width));
  line(fmt::format("  sidewalk_width: {}", s.town.sidewalk_width));
  line(fmt::format("  sidewalk_height: {}", s.town.sidewalk_height));
  line(fmt::format("  park_probability: {}  # chance that a block is a park with trees", s.town.park_probability));
  line(fmt::format("  min_upper_floors: {}    # floors above the 4 m ground floor", s.town.min_upper_floors));
  line(fmt::format("  max_upper_floors: {}", s.town.max_upper_floors));
  line(fmt::format("  tree_spacing: {}       # metres between street trees; 0 = none", s.town.tree_spacing));
  line(fmt::format("  parked_car_probability: {}", s.town.parked_car_probability));
  line(fmt::format("  pedestrians: {}        # moving occluders walking around blocks and across streets",
                   s.town.num_pedestrians));
  line(fmt::format("  moving_cars: {}         # cars driving around blocks", s.town.num_moving_cars));
  line(fmt::format("  photo_folder: \"{}\"      # folder of your photos (.jpg/.png) for the facades; \"\" = procedural",
                   s.town.photo_folder));
  line("camera:");
  line(fmt::format("  model: {}     # perspective (with distortion), unified (fisheye/omnidirectional) or "
                   "equirectangular (360 degree panorama)",
                   s.camera.model));
  line(fmt::format("  width: {}             # width x height x max(4, render.antialiasing^2) <= 67108864",
                   s.camera.width));
  line(fmt::format("  height: {}", s.camera.height));
  line(fmt::format("  hfov_deg: {}           # horizontal field of view; sets fx = fy when fx is 0", s.camera.hfov_deg));
  line(fmt::format("  xi: {}                  # unified model: 0 = pinhole, 1 = parabolic mirror / wide fisheye",
                   s.camera.xi));
  line(fmt::format("  fx: {}                  # pixels; 0 = from hfov_deg", s.camera.fx));
  line(fmt::format("  fy: {}", s.camera.fy));
  line(fmt::format("  cx: {}                 # pixels; negative = image centre, else 0..width (cy: 0..height)",
                   s.camera.cx));
  line(fmt::format("  cy: {}", s.camera.cy));
  line(fmt::format("  distortion: {{k1: {}, k2: {}, p1: {}, p2: {}, k3: {}}}  # OpenCV radial-tangential; k: "
                   "[-100, 100], p: [-1, 1]",
                   s.camera.distortion.k1, s.camera.distortion.k2, s.camera.distortion.p1, s.camera.distortion.p2,
                   s.camera.distortion.k3));
  line("vehicle:                 # bicycle model carrying the camera");
  line(fmt::format("  wheelbase: {}", s.vehicle.wheelbase));
  line(fmt::format("  max_steering_deg: {}", s.vehicle.max_steering_deg));
  line(fmt::format("  camera_height: {}      # metres above the ground", s.vehicle.camera_height));
  line(fmt::format("  camera_forward: {}     # metres ahead of the rear axle", s.vehicle.camera_forward));
  line(fmt::format("  camera_tilt_deg: {}      # downward tilt", s.vehicle.camera_tilt_deg));
  line(fmt::format("  escorts: {}              # people walking with the car 0.6-1 m around the camera (occluders, "
                   "Booij 2007 B.5.4)",
                   s.vehicle.escorts));
  line("route:");
  line(fmt::format("  type: {}              # auto (seeded drive with turns), loop (around blocks), crossing "
                   "(figure eight), junctions (through listed junctions), waypoints",
                   s.route.type));
  line(fmt::format("  segments: {}            # auto: number of junction-to-junction streets", s.route.segments));
  line(fmt::format("  loop: [{}, {}, {}, {}]      # loop: junction indices [i0, j0, i1, j1] of the rectangle; "
                   "crossing: i0, j0 = its south-west junction; inside the town's junction grid",
                   s.route.loop_i0, s.route.loop_j0, s.route.loop_i1, s.route.loop_j1));
  std::string points;
  for (const auto& p : s.route.waypoints) points += fmt::format("{}[{}, {}]", points.empty() ? "" : ", ", p.x(), p.y());
  line(fmt::format("  waypoints: [{}]  # waypoints: town-frame [x, y] points; 2..100000 within +-100 km, at most "
                   "100 km long",
                   points));
  std::string junctions;
  for (const auto& [i, j] : s.route.junctions) junctions += fmt::format("{}[{}, {}]", junctions.empty() ? "" : ", ", i, j);
  line(fmt::format("  junctions: [{}]  # junctions: [i, j] junction indices in order, consecutive ones on one street "
                   "(0 <= i <= town.blocks_x, 0 <= j <= town.blocks_y)",
                   junctions));
  line("drive:");
  line(fmt::format("  max_speed: {}            # m/s on straight streets", s.drive.max_speed));
  line(fmt::format("  max_lateral_acceleration: {}  # m/s^2: sets how much the car slows down in turns",
                   s.drive.max_lateral_acceleration));
  line(fmt::format("  max_acceleration: {}", s.drive.max_acceleration));
  line(fmt::format("  max_deceleration: {}", s.drive.max_deceleration));
  line(fmt::format("  corner_radius: {}        # metres, rounding of the route's corners", s.drive.corner_radius));
  line(fmt::format("  start_at_rest: {}", b(s.drive.start_at_rest)));
  line(fmt::format("  lateral_offset: {}       # metres right of the route", s.drive.lateral_offset));
  line(fmt::format("  wobble_amplitude: {}     # metres of seeded sideways wobble", s.drive.wobble_amplitude));
  line(fmt::format("  wobble_wavelength: {}", s.drive.wobble_wavelength));
  line(fmt::format("  wobble_seed: {}", s.drive.wobble_seed));
  line("lighting:");
  line(fmt::format("  sun_azimuth_deg: {}    # compass direction of the sun, clockwise from north (east = 90)",
                   s.lighting.sun_azimuth_deg));
  line(fmt::format("  sun_elevation_deg: {}   # above the horizon; <= 0 = no direct sun", s.lighting.sun_elevation_deg));
  line(fmt::format("  sun_irradiance: {}", s.lighting.sun_irradiance));
  line(fmt::format("  sky_irradiance: {}", s.lighting.sky_irradiance));
  line("sensor:");
  line(fmt::format("  exposure: {}", s.sensor.exposure));
  line(fmt::format("  gain: {}", s.sensor.gain));
  line(fmt::format("  noise_sigma: {}          # grey levels of Gaussian noise", s.sensor.noise_sigma));
  line(fmt::format("  color: {}            # colour PNGs instead of grey", b(s.sensor.color)));
  line("render:");
  line(fmt::format("  antialiasing: {}         # edge samples: 1 = off, 2 = pixel corners (quincunx), n = n x n grid",
                   s.render.antialiasing));
  line(fmt::format("  edge_contrast: {}        # grey levels an edge must show to get edge samples",
                   s.render.edge_contrast));
  line(fmt::format("  filter_textures: {}   # mip-mapped anisotropic texture filtering", b(s.render.filter_textures)));
  line(fmt::format("  shadows: {}", b(s.render.shadows)));
  line(fmt::format("  threads: {}              # 1 = render on the calling thread", s.render.num_threads));
  line("repeat:                  # what --variant repeat changes: another time of day and a shifted drive");
  line(fmt::format("  sun_azimuth_deg: {}", s.repeat.lighting.sun_azimuth_deg));
  line(fmt::format("  sun_elevation_deg: {}", s.repeat.lighting.sun_elevation_deg));
  line(fmt::format("  sun_irradiance: {}", s.repeat.lighting.sun_irradiance));
  line(fmt::format("  sky_irradiance: {}", s.repeat.lighting.sky_irradiance));
  line(fmt::format("  exposure: {}", s.repeat.exposure));
  line(fmt::format("  lateral_offset: {}       # metres, added to drive.lateral_offset", s.repeat.lateral_offset));
  line(fmt::format("  wobble_amplitude: {}", s.repeat.wobble_amplitude));
  line(fmt::format("  time_offset: {}         # seconds: pedestrians and cars are elsewhere", s.repeat.time_offset));
  return o;
}

}  // namespace retrace
