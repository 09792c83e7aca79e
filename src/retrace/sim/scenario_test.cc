#include "retrace/sim/scenario.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "retrace/sim/scenario_io.h"
#include "retrace/sim/simulator.h"
#include "retrace/sim/town.h"
#include "retrace/util/error.h"

namespace retrace {
namespace {

// A 3 x 3 junction grid with 60 m blocks (no town built: routes only need the street lines).
TownLayout GridLayout() {
  TownLayout layout;
  layout.street_x = {0.0, 60.0, 120.0};
  layout.street_y = {0.0, 60.0, 120.0};
  return layout;
}

// Where segments p0-p1 and q0-q1 cross (ends half-open: [p0, p1)), as the parameter along p; -1 when they do not.
double Crossing(const Vector2d& p0, const Vector2d& p1, const Vector2d& q0, const Vector2d& q1) {
  const Vector2d r = p1 - p0, s = q1 - q0;
  const double denominator = r.x() * s.y() - r.y() * s.x();
  if (std::abs(denominator) < 1e-12) return -1.0;
  const Vector2d d = q0 - p0;
  const double t = (d.x() * s.y() - d.y() * s.x()) / denominator;
  const double u = (d.x() * r.y() - d.y() * r.x()) / denominator;
  return t >= 0.0 && t < 1.0 && u >= 0.0 && u < 1.0 ? t : -1.0;
}

TEST(ScenarioTest, CrossingRouteCrossesItselfAtRightAnglesOnce) {
  Scenario scenario;
  scenario.route.type = "crossing";
  scenario.route.loop_i0 = 0;
  scenario.route.loop_j0 = 0;
  const TownLayout layout = GridLayout();
  const std::vector<Vector2d> junctions = FigureEightJunctions(layout, 0, 0);
  ASSERT_EQ(junctions.size(), 9u);  // eight streets, back at the start
  EXPECT_NEAR((junctions.front() - junctions.back()).norm(), 0.0, 1e-12);

  // The driven path (right lane, rounded corners) sampled every metre: one crossing of two passes far apart along
  // the route, at right angles near the middle junction. The start and the end meet too (the route is closed), which
  // is not counted: only pairs of samples more than 20 m from the route's ends.
  const RoutePath path(ResolveRoute(scenario, layout), scenario.drive);
  std::vector<Vector2d> p;
  for (double s = 0.0; s <= path.length(); s += 1.0) p.push_back(path.Position(s));
  int crossings = 0;
  for (size_t a = 20; a + 21 < p.size(); ++a) {
    for (size_t b = a + 10; b + 21 < p.size(); ++b) {
      if (Crossing(p[a], p[a + 1], p[b], p[b + 1]) < 0.0) continue;
      ++crossings;
      EXPECT_GT(b - a, 200u);  // not a kink: the passes are hundreds of metres apart along the route
      EXPECT_LT((p[a] - layout.Junction(1, 1)).norm(), 5.0);
      const Vector2d da = (p[a + 1] - p[a]).normalized(), db = (p[b + 1] - p[b]).normalized();
      EXPECT_LT(std::abs(da.dot(db)), 0.1);  // perpendicular
    }
  }
  EXPECT_EQ(crossings, 1);
  // Eight streets of 60 m, shortened by the rounded corners.
  EXPECT_NEAR(path.length(), 8 * 60.0, 40.0);

  // The 2 x 2 blocks must fit in the town.
  scenario.town.blocks_x = 1;
  EXPECT_NE(scenario.Validate().find("crossing"), std::string::npos);
  scenario.town.blocks_x = 2;
  scenario.town.blocks_y = 2;
  EXPECT_EQ(scenario.Validate(), "");
}

TEST(ScenarioTest, CommandLineOverridesReachTheScenarioAndItsRepeatVariant) {
  Scenario scenario;
  const Scenario defaults = scenario;
  ScenarioOverrides none;
  EXPECT_EQ(none.Apply(&scenario), "");
  EXPECT_EQ(scenario.drive.max_speed, defaults.drive.max_speed);
  EXPECT_EQ(scenario.repeat.lateral_offset, defaults.repeat.lateral_offset);

  ScenarioOverrides o;
  o.frames = 900;
  o.width = 160;
  o.height = 120;
  o.seed = 104;
  o.route = "crossing";
  o.segments = 14;
  o.max_speed = 15.0;
  o.frame_rate = 5.0;
  o.pedestrians = 80;
  o.lighting = "noon";
  o.repeat_lighting = "dusk";
  o.lateral_offset = 2.5;
  ASSERT_EQ(o.Apply(&scenario), "");
  EXPECT_EQ(scenario.num_frames, 900);
  EXPECT_EQ(scenario.camera.width, 160);
  EXPECT_EQ(scenario.camera.height, 120);
  EXPECT_EQ(scenario.seed, 104u);
  EXPECT_EQ(scenario.town.seed, 104u);
  EXPECT_EQ(scenario.route.type, "crossing");
  EXPECT_EQ(scenario.route.segments, 14);
  EXPECT_EQ(scenario.drive.max_speed, 15.0);
  EXPECT_EQ(scenario.frame_rate, 5.0);
  EXPECT_EQ(scenario.town.num_pedestrians, 80);
  EXPECT_EQ(scenario.Validate(), "");

  const LightingPreset* noon = FindLightingPreset("noon");
  const LightingPreset* dusk = FindLightingPreset("dusk");
  ASSERT_NE(noon, nullptr);
  ASSERT_NE(dusk, nullptr);
  const Scenario teach = ApplyVariant(scenario, ScenarioVariant::kTeach);
  EXPECT_EQ(teach.lighting.sun_elevation_deg, noon->lighting.sun_elevation_deg);
  EXPECT_EQ(teach.sensor.exposure, noon->exposure);
  EXPECT_EQ(teach.drive.lateral_offset, 0.0);
  const Scenario repeat = ApplyVariant(scenario, ScenarioVariant::kRepeat);
  EXPECT_EQ(repeat.lighting.sun_elevation_deg, dusk->lighting.sun_elevation_deg);
  EXPECT_EQ(repeat.lighting.sky_irradiance, dusk->lighting.sky_irradiance);
  EXPECT_EQ(repeat.sensor.exposure, dusk->exposure);
  EXPECT_EQ(repeat.drive.lateral_offset, 2.5);
  EXPECT_EQ(repeat.drive.max_speed, 15.0);
  EXPECT_EQ(repeat.frame_rate, 5.0);

  // Every preset is a valid light; dusk has no direct sun, overcast no sun either but a brighter sky than noon.
  for (const LightingPreset& preset : LightingPresets()) {
    Scenario lit;
    lit.lighting = preset.lighting;
    lit.sensor.exposure = preset.exposure;
    EXPECT_EQ(lit.Validate(), "") << preset.name;
  }
  EXPECT_LE(dusk->lighting.sun_elevation_deg, 0.0);
  EXPECT_EQ(FindLightingPreset("overcast")->lighting.sun_irradiance, 0.0);
  EXPECT_GT(FindLightingPreset("overcast")->lighting.sky_irradiance, noon->lighting.sky_irradiance);
  EXPECT_EQ(FindLightingPreset("sunset"), nullptr);
}

TEST(ScenarioTest, BadOverridesNameTheOptionAndLeaveTheScenarioAlone) {
  const auto problem = [](const ScenarioOverrides& o) {
    Scenario scenario;
    const std::string message = o.Apply(&scenario);
    EXPECT_EQ(scenario.drive.max_speed, Scenario().drive.max_speed);
    EXPECT_EQ(scenario.repeat.lateral_offset, Scenario().repeat.lateral_offset);
    return message;
  };
  ScenarioOverrides o;
  o.lateral_offset = 2.0;  // valid, but not applied when another value is bad
  o.max_speed = 0.0;
  EXPECT_EQ(problem(o), "--speed: must be in [0.5, 50] m/s, got 0");
  o.max_speed.reset();
  o.frame_rate = -10.0;
  EXPECT_EQ(problem(o), "--frame-rate: must be in [0.1, 1000] Hz, got -10");
  o.frame_rate.reset();
  o.pedestrians = -1;
  EXPECT_EQ(problem(o), "--pedestrians: must be in 0..1000, got -1");
  o.pedestrians.reset();
  o.repeat_lighting = "sunset";
  EXPECT_EQ(problem(o), "--repeat-lighting: unknown lighting 'sunset' (noon, low-sun, dusk or overcast)");
  o.repeat_lighting.reset();
  o.route = "spiral";
  EXPECT_EQ(problem(o), "--route: unknown route 'spiral' (auto, loop or crossing)");
  o.route.reset();
  o.lateral_offset = 12.0;
  EXPECT_EQ(problem(o), "--lateral-offset: must be in [-10, 10] m, got 12");
}

// A scenario file that sets one key ("town.pedestrians" -> "town:\n  pedestrians: 5\n") plus `extra` top-level
// text; the key's value is on line `*line`.
std::string FileSetting(const std::string& key, const std::string& value, int* line) {
  std::string text;
  std::string indent;
  size_t begin = 0;
  int lines = 0;
  for (size_t dot; (dot = key.find('.', begin)) != std::string::npos; begin = dot + 1) {
    text += indent + key.substr(begin, dot - begin) + ":\n";
    indent += "  ";
    ++lines;
  }
  text += indent + key.substr(begin) + ": " + value + "\n";
  *line = lines + 1;
  return text;
}

// Keys whose bounds are only valid together with another key: what else the file must set.
std::string Companion(const std::string& key, double value) {
  if (key == "town.block_size_min") return fmt::format("  block_size_max: {}\n", value);
  if (key == "town.max_upper_floors") return fmt::format("  min_upper_floors: {}\n", std::min(value, 1.0));
  if (key == "town.min_upper_floors") return fmt::format("  max_upper_floors: {}\n", value);
  if (key == "town.block_size_max") return fmt::format("  block_size_min: {}\n", value);
  if (key == "camera.hfov_deg") return "  model: unified\n  xi: 2\n";  // a perspective camera ends at 179 degrees
  // The repeat variant adds its offsets to these: they reach their bounds alone.
  if (key == "drive.lateral_offset") return "repeat:\n  lateral_offset: 0\n";
  if (key == "time_offset") return "repeat:\n  time_offset: 0\n";
  return "";
}

std::string ParseProblem(const std::string& text) {
  try {
    ParseScenario(text, "town.yaml");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// Every numeric key of a scenario file: both bounds of its documented range are accepted, the values just outside
// are refused with one line that names the file, the line, the key, the range and the value.
TEST(ScenarioRangeTest, EveryKeyAcceptsItsBoundsAndRefusesValuesOutsideThem) {
  ASSERT_GE(ScenarioKeyRanges().size(), 60u);
  for (const ScenarioKeyRange& range : ScenarioKeyRanges()) {
    const std::string key = range.key;
    for (const double bound : {range.min, range.max}) {
      int line = 0;
      std::string text = FileSetting(key, fmt::format("{}", bound), &line);
      text += Companion(key, bound);
      EXPECT_EQ(ParseProblem(text), "") << key << " = " << bound << "\n" << text;
    }
    if (range.zero_allowed) {
      int line = 0;
      EXPECT_EQ(ParseProblem(FileSetting(key, "0", &line)), "") << key;
    }
    const double step = range.integer ? 1.0 : std::max(1e-3, 1e-3 * std::abs(range.max - range.min));
    const double below = range.zero_allowed && range.min > 0.0 ? 0.5 * range.min : range.min - step;
    for (const double bad : {below, range.max + step}) {
      int line = 0;
      const std::string text = FileSetting(key, fmt::format("{}", bad), &line);
      EXPECT_EQ(ParseProblem(text),
                fmt::format("town.yaml: line {}: {}: must be {}, got {}", line, key, range.Text(), bad))
          << text;
    }
  }
  // A few messages in full.
  EXPECT_EQ(ParseProblem("town:\n  pedestrians: 100000000\n"),
            "town.yaml: line 2: town.pedestrians: must be in 0..1000, got 100000000");
  EXPECT_EQ(ParseProblem("route:\n  segments: 100000000\n"),
            "town.yaml: line 2: route.segments: must be in 1..1000, got 100000000");
  EXPECT_EQ(ParseProblem("seed: 1\nrender:\n  threads: 100000\n"),
            "town.yaml: line 3: render.threads: must be in 1..256, got 100000");
  EXPECT_EQ(ParseProblem("frames: -5\n"), "town.yaml: line 1: frames: must be in 0..1000000, got -5");
  EXPECT_EQ(ParseProblem("town:\n  tree_spacing: 0.001\n"),
            "town.yaml: line 2: town.tree_spacing: must be 0 or in [5, 1000] m, got 0.001");
  EXPECT_EQ(ParseProblem("drive:\n  max_speed: .nan\n"),
            "town.yaml: line 2: drive.max_speed: must be in [0.5, 50] m/s, got nan");
  EXPECT_EQ(ParseProblem("seed: -1\n"), "town.yaml: line 1: seed: expected a non-negative integer, got '-1'");
  EXPECT_EQ(ParseProblem("seed: 18446744073709551615\n"), "");
}

// vehicle.escorts (Booij 2007 §B.5.4's people walking beside the car): none by default, 0..kMaxEscorts, an integer,
// kept by the repeat variant and by a round trip through YAML.
TEST(ScenarioRangeTest, EscortsAreACountOfPeopleBesideTheCar) {
  EXPECT_EQ(Scenario().vehicle.escorts, 0);
  EXPECT_EQ(ParseScenario("vehicle:\n  escorts: 4\n", "town.yaml").vehicle.escorts, 4);
  EXPECT_EQ(ParseProblem("vehicle:\n  escorts: -1\n"), "town.yaml: line 2: vehicle.escorts: must be in 0..8, got -1");
  EXPECT_EQ(ParseProblem("vehicle: {wheelbase: 2.5, escorts: 9}\n"),
            "town.yaml: line 1: vehicle.escorts: must be in 0..8, got 9");
  EXPECT_EQ(ParseProblem("vehicle:\n  escorts: 1.5\n"),
            "town.yaml: line 2: vehicle.escorts: expected an integer, got '1.5'");
  EXPECT_EQ(ParseProblem("vehicle:\n  escort: 1\n"), "town.yaml: line 2: vehicle.escort: unknown key");
  Scenario scenario;
  scenario.vehicle.escorts = 3;
  EXPECT_EQ(ParseScenario(ScenarioToYaml(scenario), "round trip").vehicle.escorts, 3);
  EXPECT_EQ(ApplyVariant(scenario, ScenarioVariant::kRepeat).vehicle.escorts, 3);
  scenario.vehicle.escorts = -2;
  EXPECT_EQ(scenario.Validate(), "vehicle.escorts: must be in 0..8, got -2");
}

// The rules that tie keys together, with the key at fault named.
TEST(ScenarioRangeTest, RulesBetweenKeys) {
  EXPECT_EQ(ParseProblem("town:\n  block_size_min: 60\n"),
            "town.yaml: town.block_size_max: must be >= town.block_size_min (60), got 55");
  EXPECT_EQ(ParseProblem("town:\n  min_upper_floors: 3\n  max_upper_floors: 2\n"),
            "town.yaml: line 3: town.max_upper_floors: must be >= town.min_upper_floors (3), got 2");
  // The renderer's memory: width x height x max(4, antialiasing^2) <= 2^26.
  EXPECT_EQ(ParseProblem("camera:\n  width: 4096\n  height: 4096\n"), "");
  EXPECT_EQ(ParseProblem("camera:\n  width: 1024\n  height: 1024\nrender:\n  antialiasing: 8\n"), "");
  EXPECT_NE(ParseProblem("camera:\n  width: 1025\n  height: 1024\nrender:\n  antialiasing: 8\n")
                .find("town.yaml: line 2: camera.width: 1025 x 1024 pixels at render.antialiasing 8 exceed the "
                      "renderer's memory budget"),
            std::string::npos);
  EXPECT_NE(ParseProblem("camera:\n  width: 8192\n  height: 8192\n").find("camera.width: 8192 x 8192 pixels"),
            std::string::npos);
  EXPECT_EQ(ParseProblem("drive:\n  lateral_offset: 9.5\n"),
            "town.yaml: repeat.lateral_offset: the repeat drive's offset drive.lateral_offset + repeat.lateral_offset "
            "must be in [-10, 10] m, got 10.5");
  EXPECT_EQ(ParseProblem("time_offset: -1000000\nrepeat:\n  time_offset: -1\n"),
            "town.yaml: line 3: repeat.time_offset: the repeat drive's clock time_offset + repeat.time_offset must be "
            "in [-1000000, 1000000] s, got -1000001");
  EXPECT_EQ(ParseProblem("camera:\n  hfov_deg: 179.5\n"),
            "town.yaml: line 2: camera.hfov_deg: must be in [1, 179] degrees for a perspective camera, got 179.5");
  EXPECT_EQ(ParseProblem("camera:\n  cx: -1\n  cy: 240\n"), "");
  EXPECT_EQ(ParseProblem("camera:\n  cx: 320.5\n"),
            "town.yaml: line 2: camera.cx: must be negative (the image centre) or in [0, 320] pixels, got 320.5");
  EXPECT_EQ(ParseProblem("route:\n  type: loop\n  loop: [0, 0, 5, 1]\n"),
            "town.yaml: line 3: route.loop: [i0, j0, i1, j1] must have 0 <= i0 < i1 <= town.blocks_x (4) and 0 <= "
            "j0 < j1 <= town.blocks_y (4), got [0, 0, 5, 1]");
  EXPECT_EQ(ParseProblem("route:\n  type: waypoints\n  waypoints: [[0, 0]]\n"),
            "town.yaml: line 3: route.waypoints: a waypoints route needs 2..100000 points, got 1");
  EXPECT_EQ(ParseProblem("route:\n  type: waypoints\n  waypoints: [[0, 0], [1e6, 0]]\n"),
            "town.yaml: line 3: route.waypoints[1]: coordinates must be within +-100000 m, got [1000000, 0]");
  EXPECT_EQ(ParseProblem("route:\n  type: waypoints\n  waypoints: [[0, 0], [90000, 0], [0, 0]]\n"),
            "town.yaml: line 3: route.waypoints: the route must be 1..100000 m long, got 180000.0 m");
  // Routes through listed junctions: inside the grid, consecutive junctions along one street.
  EXPECT_EQ(ParseProblem("route:\n  type: junctions\n  junctions: [[0, 0], [2, 0], [2, 3]]\n"), "");
  EXPECT_EQ(ParseProblem("route:\n  type: junctions\n  junctions: [[0, 0]]\n"),
            "town.yaml: line 3: route.junctions: a junctions route needs 2..100000 junctions, got 1");
  EXPECT_EQ(ParseProblem("route:\n  type: junctions\n  junctions: [[0, 0], [5, 0]]\n"),
            "town.yaml: line 3: route.junctions[1]: [i, j] must have 0 <= i <= town.blocks_x (4) and 0 <= j <= "
            "town.blocks_y (4), got [5, 0]");
  EXPECT_EQ(ParseProblem("route:\n  type: junctions\n  junctions: [[0, 0], [1, 1]]\n"),
            "town.yaml: line 3: route.junctions[1]: [1, 1] is not along one street from [0, 0] (one index must stay)");
  EXPECT_EQ(ParseProblem("route:\n  type: junctions\n  junctions: [[0, 0], [0, 0]]\n"),
            "town.yaml: line 3: route.junctions[1]: [0, 0] is not along one street from [0, 0] (one index must stay)");
  EXPECT_EQ(ParseProblem("route:\n  type: junctions\n  junctions: [[0, 0], [1, x]]\n"),
            "town.yaml: line 3: route.junctions[1]: expected two integers [i, j]");
  std::string many = "markers: [";
  for (int i = 0; i <= kMaxMarkers; ++i) many += i == 0 ? "[0, 0, 1]" : ", [0, 0, 1]";
  EXPECT_EQ(ParseProblem(many + "]\n"), "town.yaml: line 1: markers: at most 1000 markers, got 1001");
}

// The command line's overrides go through the same check as the file: `--frames -1` is refused as `frames: -5` is,
// with the option named instead of the key.
TEST(ScenarioRangeTest, OverridesAreCheckedAsTheFileIs) {
  const auto problem = [](const ScenarioOverrides& o) {
    Scenario scenario;
    return o.Apply(&scenario);
  };
  ScenarioOverrides o;
  o.frames = -1;
  EXPECT_EQ(problem(o), "--frames: must be in 0..1000000, got -1");
  o.frames = 1000000;
  EXPECT_EQ(problem(o), "");
  o = {};
  o.threads = 100000;
  EXPECT_EQ(problem(o), "--threads: must be in 1..256, got 100000");
  o.threads = 256;
  EXPECT_EQ(problem(o), "");
  o.threads = 0;
  EXPECT_EQ(problem(o), "--threads: must be in 1..256, got 0");
  o = {};
  o.pedestrians = 100000000;
  EXPECT_EQ(problem(o), "--pedestrians: must be in 0..1000, got 100000000");
  o = {};
  o.segments = 1001;
  EXPECT_EQ(problem(o), "--segments: must be in 1..1000, got 1001");
  o = {};
  o.width = 7;
  EXPECT_EQ(problem(o), "--width: must be in 8..8192 pixels, got 7");
  o.width = 8192;
  o.height = 8192;
  EXPECT_NE(problem(o).find("--width: 8192 x 8192 pixels at render.antialiasing 2 exceed"), std::string::npos);
  o = {};
  o.height = 0;
  EXPECT_EQ(problem(o), "--height: must be in 8..8192 pixels, got 0");
  o = {};
  o.seed = -1;
  EXPECT_EQ(problem(o), "--seed: must be in 0..9223372036854775807, got -1");
  // A key the file set badly for the overridden route: named as the file spells it.
  Scenario small;
  small.town.blocks_x = 1;
  o = {};
  o.route = "crossing";
  EXPECT_NE(o.Apply(&small).find("route.loop: the crossing's 2 x 2 blocks"), std::string::npos);
  EXPECT_EQ(small.route.type, "auto");  // left unchanged
}

}  // namespace
}  // namespace retrace
