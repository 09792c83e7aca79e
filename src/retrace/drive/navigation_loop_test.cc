// Closed-loop navigation in the simulator (Booij 2007 §B.4; issue 15's acceptance, shortened): a panoramic camera's
// drives along two crossing streets of a small town are taught (the second appended to the first's map, linked
// where they see the same place), and the car, placed where the first drive's repeat variant starts (1 m to the
// side, another sun), is driven by the Navigator alone to a key-image of the second drive about 25 m past the
// crossing: it must turn where neither drive turned. Ground truth: the camera's distance from the goal key-image's
// place when the navigator stops, the length of the drive against the streets between start and goal, and the
// largest distance from the path planned at the time (a wrong turn). And, with the same map, a car that drives
// straight on where the plan turns: the localizer beneath the navigator notices and the plan starts again from there.

#include "retrace/drive/navigation_loop.h"

#include <array>
#include <cmath>
#include <optional>
#include <unordered_map>
#include <vector>

#include <gtest/gtest.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "retrace/sim/recording.h"
#include "retrace/teach/teacher.h"

namespace retrace {
namespace {

TEST(NavigationLoopOptions, CheckRejectsBadValues) {
  NavigationLoopOptions options;
  EXPECT_TRUE(options.Check());
  options.frame_period = 0;
  EXPECT_FALSE(options.Check());
  options = NavigationLoopOptions();
  options.max_stopped_frames = 0;
  EXPECT_FALSE(options.Check());
}

// Known answers: beside a segment, beyond its end, at a corner, a single point.
TEST(DistanceToPolyline, KnownAnswers) {
  const std::vector<Vector2d> corner = {Vector2d(0, 0), Vector2d(10, 0), Vector2d(10, 10)};
  EXPECT_DOUBLE_EQ(DistanceToPolyline(corner, Vector2d(5, 3)), 3.0);
  EXPECT_DOUBLE_EQ(DistanceToPolyline(corner, Vector2d(-3, -4)), 5.0);
  EXPECT_DOUBLE_EQ(DistanceToPolyline(corner, Vector2d(14, 5)), 4.0);
  EXPECT_DOUBLE_EQ(DistanceToPolyline(corner, Vector2d(13, -4)), 5.0);
  EXPECT_DOUBLE_EQ(DistanceToPolyline({Vector2d(1, 1)}, Vector2d(4, 5)), 5.0);
  EXPECT_TRUE(std::isinf(DistanceToPolyline({}, Vector2d(0, 0))));
}

TEST(NavigatorOptions, CheckRejectsBadValues) {
  NavigatorOptions options;
  EXPECT_TRUE(options.Check());
  options.min_similarity = 0;
  EXPECT_FALSE(options.Check());
  options = NavigatorOptions();
  options.look_ahead = -1;
  EXPECT_FALSE(options.Check());
  options = NavigatorOptions();
  options.speed = 0;
  EXPECT_FALSE(options.Check());
}

Scenario StreetScenario(std::vector<std::array<int, 2>> junctions) {
  Scenario scenario;
  scenario.seed = 5;
  scenario.town.seed = 5;
  scenario.town.blocks_x = 3;
  scenario.town.blocks_y = 2;
  scenario.town.num_pedestrians = 0;
  scenario.town.num_moving_cars = 0;
  scenario.camera.model = "equirectangular";
  scenario.camera.width = 640;
  scenario.camera.height = 320;
  scenario.route.type = "junctions";
  scenario.route.junctions = std::move(junctions);
  return scenario;
}

// Route 0 east through the junctions (0,1) (1,1) (2,1); route 1 north through (1,0) (1,1) (1,2): they cross at (1,1).
// Taught once for the tests below (in-process: route 1 appended to route 0's map, linked where they see one place).
struct CrossingMap {
  std::array<Scenario, 2> scenarios = {StreetScenario({{{0, 1}}, {{1, 1}}, {{2, 1}}}),
                                       StreetScenario({{{1, 0}}, {{1, 1}}, {{1, 2}}})};
  Map map;
  std::unordered_map<node_t, Vector2d> truth;  // key-images' places, town frame
  Vector2d junction = Vector2d::Zero();        // route 1's key-image nearest route 0's street
  node_t goal = kInvalidNodeId;                // route 1's key-image nearest 25 m north of the crossing
};

const CrossingMap& TaughtCrossing() {
  static const CrossingMap taught = [] {
    CrossingMap c;
    for (int route = 0; route < 2; ++route) {
      const RecordedDrive teach = RecordDrive(ApplyVariant(c.scenarios[route], ScenarioVariant::kTeach));
      Teacher teacher(*teach.camera, TeachOptions(), nullptr);
      if (route == 1) teacher.AppendTo(c.map);
      for (const Frame& frame : teach.frames) teacher.AddFrame(frame);
      teacher.Finish();
      // An appended teacher's map holds the new drive and its joins (teach --append adds them to the map's file).
      for (const MapNode& node : teacher.map().nodes()) c.map.AddNode(node);
      for (const MapArc& arc : teacher.map().arcs()) c.map.AddArc(arc);
      for (const NodeScale& scale : teacher.map().scales()) c.map.AddScale(scale);
      const Rigid3d town_from_world = Simulator(c.scenarios[route]).town_from_world();
      for (const MapNode& node : c.map.nodes()) {
        if (node.route != route) continue;
        c.truth[node.id] = (town_from_world * teach.truth[node.source_frame].world_from_cam).translation.head<2>();
      }
    }
    double best = 1e9;
    for (const MapNode& node : c.map.nodes()) {
      if (node.route == 1 && std::abs(c.truth.at(node.id).y() - c.truth.at(0).y()) < best) {
        best = std::abs(c.truth.at(node.id).y() - c.truth.at(0).y());
        c.junction = c.truth.at(node.id);
      }
    }
    best = 1e9;
    for (const MapNode& node : c.map.nodes()) {
      const Vector2d d = c.truth.at(node.id) - c.junction;
      if (node.route == 1 && d.y() > 0 && std::abs(d.y() - 25.0) < best) {
        best = std::abs(d.y() - 25.0);
        c.goal = node.id;
      }
    }
    return c;
  }();
  return taught;
}

TEST(NavigationLoop, PanoramicCarTurnsWhereNoDriveTurned) {
  const CrossingMap& crossing = TaughtCrossing();
  const std::array<Scenario, 2>& scenarios = crossing.scenarios;
  const std::unordered_map<node_t, Vector2d>& truth = crossing.truth;
  const Map& map = crossing.map;
  int joins = 0;
  for (const MapArc& arc : map.arcs()) joins += arc.kind == "join";
  ASSERT_GE(joins, 1) << "the two drives were not linked at their crossing";
  const node_t goal = crossing.goal;
  ASSERT_NE(goal, kInvalidNodeId);
  const Vector2d goal_position = truth.at(goal);

  Simulator simulator(ApplyVariant(scenarios[0], ScenarioVariant::kRepeat));
  Navigator navigator(map, simulator.camera(), goal);
  NavigationLoopOptions options;
  options.frame_period = 1.0 / scenarios[0].frame_rate;
  options.max_frames = 800;
  std::string steps;  // per frame: subgoal, heading, relocalization (printed on failure)
  const NavigationLoopSummary summary =
      DriveToGoal(&simulator, &navigator, options, truth, [&](const NavigationLoopStep& s) {
        steps += fmt::format("{}{}{}{} ", s.step->subgoal,
                             s.step->heading ? fmt::format("/{:.2f}", *s.step->heading) : "",
                             s.step->along_arc ? "A" : "", s.step->relocalized ? "R" : "");
      });
  const double off_path = summary.max_off_plan_m;
  ASSERT_FALSE(summary.camera_positions.empty());
  const Vector2d start_to_goal = goal_position - summary.camera_positions.front();
  const double streets = std::abs(start_to_goal.x()) + std::abs(start_to_goal.y());  // along the two streets
  const double off_goal = (summary.camera_positions.back() - goal_position).norm();
  spdlog::info("navigation across the junction to key-image {}: {} frames, reached {}, {:.2f} m from the goal, "
               "driven {:.1f} m for {:.1f} m, at most {:.1f} m from the planned path, {} relocalizations, {} frames "
               "without a heading, {} steered by the image, {} replans", goal, summary.frames, summary.reached_goal, off_goal,
               summary.path_length_m, streets, off_path, summary.relocalizations, summary.frames_without_heading,
               summary.image_steering_frames, summary.replans);
  EXPECT_TRUE(summary.reached_goal) << steps;
  EXPECT_FALSE(summary.left_streets);
  EXPECT_LT(off_goal, 2.0);                           // issue 15: stop within 2 m of the goal
  EXPECT_LT(std::abs(summary.path_length_m / streets - 1.0), 0.1);  // ... after a drive within 10 % of the streets
  EXPECT_LT(off_path, 8.0) << steps;                  // no wrong turn: within a road's width of the plan
  EXPECT_LT(summary.frames_without_heading, summary.frames / 4) << steps;
  // The localizer beneath: image steering (Segvic 2009 eq. (10)) along route 0's taught arcs before the turn, and no
  // replanning — the car never left the plan (an overshoot into the crossing is not another branch).
  EXPECT_GT(summary.image_steering_frames, summary.frames / 4) << steps;
  EXPECT_EQ(summary.replans, 0) << steps;
}

// The car drives route 0 straight through the crossing (the simulator's autopilot) while the plan turns north onto
// route 1: the localizer beneath the navigator must notice the other branch and the navigator replan from where the
// car is — not before the crossing, and within a couple of arcs after it.
TEST(NavigationLoop, ThePlanFollowsACarThatTookAnotherBranch) {
  const CrossingMap& crossing = TaughtCrossing();
  ASSERT_NE(crossing.goal, kInvalidNodeId);
  Simulator simulator(ApplyVariant(crossing.scenarios[0], ScenarioVariant::kRepeat));
  Navigator navigator(crossing.map, simulator.camera(), crossing.goal);
  SimFrame view;
  int frames = 0;
  std::optional<Vector2d> replanned_at;
  node_t replanned_from = kInvalidNodeId;
  while (simulator.NextFrame(&view) && !replanned_at) {
    const NavigationStep step = navigator.ProcessImage(view.image);
    ++frames;
    if (step.replanned) {
      replanned_at = view.town_from_cam.translation.head<2>();
      replanned_from = navigator.planned_path().nodes.front();
    }
  }
  ASSERT_TRUE(replanned_at.has_value()) << "the car drove on along route 0 for " << frames
                                        << " frames and the plan still turned at the crossing";
  const double past_crossing = replanned_at->x() - crossing.junction.x();  // route 0 runs east
  spdlog::info("replanned {:.1f} m past the crossing (frame {}) from key-image {} of route {}, {:.1f} m from the car",
               past_crossing, frames, replanned_from, crossing.map.FindNode(replanned_from)->route,
               (crossing.truth.at(replanned_from) - *replanned_at).norm());
  EXPECT_GT(past_crossing, 0.0);
  EXPECT_LT(past_crossing, 20.0);
  // From where the car is: a key-image of route 0 beyond the crossing, ahead of the car by at most an arc or two.
  EXPECT_EQ(crossing.map.FindNode(replanned_from)->route, 0);
  EXPECT_GT(crossing.truth.at(replanned_from).x(), crossing.junction.x());
  EXPECT_LT((crossing.truth.at(replanned_from) - *replanned_at).norm(), 10.0);
  EXPECT_EQ(navigator.replans(), 1);
}

}  // namespace
}  // namespace retrace
