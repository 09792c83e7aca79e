#include "retrace/sim/scenario.h"

#include <cmath>

#include <gtest/gtest.h>

#include "retrace/sim/simulator.h"
#include "retrace/sim/town.h"

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
  for (const LightingPreset& preset : LightingPresets()) EXPECT_TRUE(preset.lighting.Check()) << preset.name;
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
  EXPECT_EQ(problem(o), "--speed: must be in (0, 50] m/s, got 0");
  o.max_speed.reset();
  o.frame_rate = -10.0;
  EXPECT_EQ(problem(o), "--frame-rate: must be in (0, 1000] Hz, got -10");
  o.frame_rate.reset();
  o.pedestrians = -1;
  EXPECT_EQ(problem(o), "--pedestrians: must be >= 0, got -1");
  o.pedestrians.reset();
  o.repeat_lighting = "sunset";
  EXPECT_EQ(problem(o), "--repeat-lighting: unknown lighting 'sunset' (noon, low-sun, dusk or overcast)");
  o.repeat_lighting.reset();
  o.route = "spiral";
  EXPECT_EQ(problem(o), "--route: unknown route 'spiral' (auto, loop or crossing)");
  o.route.reset();
  o.lateral_offset = 12.0;
  EXPECT_EQ(problem(o), "--lateral-offset: must be within +-10 m, got 12");
}

}  // namespace
}  // namespace retrace
