#pragma once

// A simulation scenario: everything that defines a recorded drive (world, camera, vehicle, route, driving style,
// light, sensor, rendering, frame rate), as plain data. scenario_io.h reads and writes it as YAML; the command line
// can override fields. A scenario has two variants of one drive:
//  - teach: the drive as specified;
//  - repeat: the same route with the `repeat` overrides (by default another time of day — sun on the other side,
//    lower, different exposure — a 1 m lateral offset, some wobble, other sensor noise and other positions of the
//    moving pedestrians and cars), so that "teach" and "repeat" recordings come from one scenario and one flag.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "retrace/camera/camera_model.h"
#include "retrace/camera/perspective_camera.h"
#include "retrace/sim/renderer.h"
#include <array>

#include "retrace/sim/town.h"
#include "retrace/sim/vehicle.h"

namespace retrace {

struct CameraSpec {
  // "perspective" (pinhole + radial-tangential distortion), "unified" (fisheye / catadioptric omnidirectional,
  // Mei 2007, with xi) or "equirectangular" (360 x 180 degree panorama).
  std::string model = "perspective";
  int width = 320;
  int height = 240;
  // Horizontal field of view (degrees) that sets fx = fy when `fx` is 0 (perspective < 180, unified any).
  double hfov_deg = 80.0;
  // Mirror / fisheye parameter of the unified model (0 = perspective, 1 = parabolic mirror / ~180+ degree fisheye).
  double xi = 1.0;
  // Intrinsics in pixels (perspective); fx = 0 means "from hfov_deg", cx/cy < 0 mean the image centre.
  double fx = 0.0, fy = 0.0, cx = -1.0, cy = -1.0;
  LensDistortion distortion;

  std::unique_ptr<CameraModel> MakeCamera() const;
};

struct RouteSpec {
  // "auto": a seeded drive of `segments` junction-to-junction streets with turns; "loop": around the rectangle of
  // blocks [loop_i0, loop_i1] x [loop_j0, loop_j1] (junction indices); "crossing": a figure eight over the 2 x 2
  // blocks from junction (loop_i0, loop_j0) that crosses itself at (loop_i0 + 1, loop_j0 + 1) (town.h,
  // FigureEightJunctions); "junctions": through the listed junctions [i, j] in order (consecutive ones on one
  // street; straight through or turning, so that routes laid by hand cross or share streets), in the right lane;
  // "waypoints": the given town-frame points (X east, Y north, metres), driven as given (no lane offset).
  std::string type = "auto";
  int segments = 8;
  int loop_i0 = 0, loop_j0 = 0, loop_i1 = 2, loop_j1 = 1;
  std::vector<Vector2d> waypoints;
  std::vector<std::array<int, 2>> junctions;  // "junctions": junction indices [i, j] (town.h TownLayout::Junction)
};

// Overrides for the repeat recording of a route.
struct RepeatSpec {
  Lighting lighting{250.0, 25.0, 1.2, 0.6};
  double exposure = 0.9;
  double lateral_offset = 1.0;     // metres right of the route (teach drives at the scenario's offset)
  double wobble_amplitude = 0.25;  // metres
  double time_offset = 37.0;       // seconds added to the clock of the moving occluders
};

// What is wrong with a scenario: the key at fault as a scenario file spells it ("town.pedestrians") and a sentence
// with the allowed range and the value, e.g. "must be in 0..1000, got 100000000".
struct ScenarioProblem {
  std::string key;
  std::string message;

  std::string ToString() const { return key + ": " + message; }
};

struct Scenario {
  // Seed of the world and of everything random in the drive (the town uses town.seed, derived from this unless
  // given explicitly in the file).
  uint64_t seed = 1;
  TownOptions town;
  // A scene file of the user's (glTF, OBJ, ... via Assimp) instead of the built-in town; empty = the town. Needs
  // route.type "waypoints" (in the file's ground plane, metres after scaling).
  std::string scene_file;
  double scene_scale = 1.0;  // metres per file unit
  bool scene_y_up = true;    // the file's up axis is Y (glTF convention) rather than Z
  CameraSpec camera;
  VehicleOptions vehicle;
  RouteSpec route;
  DriveOptions drive;
  Lighting lighting;
  SensorOptions sensor;
  RenderOptions render;
  // Frames per second of the recording and number of frames (0 = until the end of the route). The drive always
  // stops at the route's end: a larger count gives fewer frames (RecordSummary says how many).
  double frame_rate = 10.0;
  int num_frames = 0;
  // Seconds on the occluders' clock at the first frame.
  double time_offset = 0.0;
  // Calibration markers: self-luminous spheres at these points of the output world frame (simulator.h), for
  // checking projections against ground truth (e.g. in the dark: sun_elevation_deg < 0, sky_irradiance 0).
  std::vector<Vector3d> markers;
  double marker_radius = 0.1;
  double marker_brightness = 0.8;
  RepeatSpec repeat;

  // Checks every field against its documented range (ScenarioKeyRanges) and the rules that tie fields together;
  // returns the first problem, or nothing when the scenario is valid. The one place where scenarios are checked:
  // scenario files (scenario_io.h) and the command line's overrides (ScenarioOverrides) both come through here.
  std::optional<ScenarioProblem> Check() const;
  // Check() as one line "key: problem", or "" when the scenario is valid.
  std::string Validate() const;
};

// The documented range of a numeric scenario key. Values outside it are refused before anything is built (a huge
// count or size would exhaust the memory or the threads of the machine first). Ranges are inclusive.
struct ScenarioKeyRange {
  const char* key;     // as a scenario file spells it: "town.pedestrians", "render.threads"
  double min, max;
  bool integer;
  bool zero_allowed;   // 0 (= none / off / automatic) is allowed besides [min, max]
  const char* unit;    // "m", "m/s", "" ...

  // "0..1000", "[0.5, 50] m/s", "0 or [2, 1000] m".
  std::string Text() const;
  bool Contains(double value) const;
};

// The range of every numeric key of a scenario file with a fixed range, in the order of the file. Keys not listed:
// the seeds (any integer 0..2^64-1), camera.cx / cy (negative = the image centre, else 0..width / height), and the
// rules that tie keys together, checked by Scenario::Check: town.block_size_max >= block_size_min,
// town.max_upper_floors >= min_upper_floors, camera.hfov_deg below 179 for perspective cameras, image size x
// antialiasing within the renderer's memory (kMaxRenderSamples), route.loop inside the town's junction grid,
// route.waypoints (2..kMaxWaypoints points within kMaxCoordinate m, a route of at most kMaxRouteLength m) and
// markers (at most kMaxMarkers, within kMaxCoordinate m).
const std::vector<ScenarioKeyRange>& ScenarioKeyRanges();
// The range of `key`, nullptr when it has none of its own.
const ScenarioKeyRange* FindScenarioKeyRange(const std::string& key);

// Width x height x max(4, antialiasing^2) of the rendered images: each sample costs the renderer about 25 bytes
// (rays, buffers, sub-sample rays), so 2^26 samples (e.g. 4096 x 4096 pixels up to antialiasing 2) is about 1.5 GB.
constexpr double kMaxRenderSamples = 67108864.0;
constexpr int kMaxWaypoints = 100000;
constexpr int kMaxMarkers = 1000;
constexpr double kMaxCoordinate = 100000.0;   // metres from the origin (waypoints, markers)
constexpr double kMaxRouteLength = 100000.0;  // metres of a waypoint route

// A named light for the command line: the sun, the sky and the exposure a camera would choose in it.
struct LightingPreset {
  const char* name;
  const char* description;
  Lighting lighting;
  double exposure;
};

// noon, low-sun, dusk, overcast.
const std::vector<LightingPreset>& LightingPresets();
// The preset of that name, nullptr when there is none.
const LightingPreset* FindLightingPreset(const std::string& name);

// Changes to a scenario given on the command line (`retrace sim render`, `sim drive`); an unset field keeps the
// scenario's value. Apply's messages name the options as the command line spells them.
struct ScenarioOverrides {
  std::optional<int> frames;             // --frames: num_frames (0 = the whole route)
  std::optional<int> width;              // --width: camera width, the field of view kept
  std::optional<int> height;             // --height
  std::optional<int64_t> seed;           // --seed: seed of the world, the auto route and the wobble
  std::optional<std::string> route;      // --route: route.type (auto, loop, crossing)
  std::optional<int> segments;           // --segments: route.segments of an auto route
  std::optional<double> max_speed;       // --speed: drive.max_speed, m/s
  std::optional<double> frame_rate;      // --frame-rate: frames per second
  std::optional<int> pedestrians;        // --pedestrians: town.num_pedestrians
  std::optional<std::string> lighting;   // --lighting: preset of the teach drive (sun, sky, exposure)
  std::optional<std::string> repeat_lighting;  // --repeat-lighting: preset of the repeat variant
  std::optional<double> lateral_offset;  // --lateral-offset: repeat.lateral_offset, metres right of the teach drive
  std::optional<int> threads;            // --threads: render.threads

  // Applies the set fields and checks the result with Scenario::Check; returns "" or a one-line explanation of the
  // first bad value, naming the option when one of them is at fault ("--frames: must be in 0..1000000, got -1").
  // The scenario is left unchanged unless all is well.
  std::string Apply(Scenario* scenario) const;
};

enum class ScenarioVariant { kTeach, kRepeat };

// The scenario with the variant's overrides applied (teach: unchanged).
Scenario ApplyVariant(const Scenario& scenario, ScenarioVariant variant);

}  // namespace retrace
