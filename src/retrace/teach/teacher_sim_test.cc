// Teach in the simulator, where ground truth is exact: loop closing, gap recovery, key-image density.

#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "retrace/sim/recording.h"
#include "retrace/teach/map_report.h"
#include "retrace/teach/teacher.h"

#include <spdlog/spdlog.h>

namespace retrace {
namespace {

double Mean(const std::vector<double>& v) {
  double sum = 0;
  for (double x : v) sum += x;
  return v.empty() ? 0.0 : sum / v.size();
}

Scenario SmallTown() {
  Scenario scenario;
  scenario.town.blocks_x = 2;
  scenario.town.blocks_y = 2;
  scenario.town.num_pedestrians = 0;
  scenario.town.num_moving_cars = 0;
  return scenario;
}

// Nodes reachable from the first node over arcs in either direction.
size_t ReachableNodes(const Map& map) { return ChainKeyImagePoses(map).size(); }

TEST(TeachSim, CircularRouteClosesTheLoop) {
  Scenario scenario = SmallTown();
  scenario.route.type = "loop";
  scenario.route.loop_i0 = 0;
  scenario.route.loop_j0 = 0;
  scenario.route.loop_i1 = 1;
  scenario.route.loop_j1 = 1;
  // Around the block once and on along the first street, so that the last key-images look where the first did.
  {
    Simulator layout_only(scenario);
    std::vector<Vector2d> waypoints = ResolveRoute(scenario, layout_only.layout());
    ASSERT_GE(waypoints.size(), 4u);
    if ((waypoints.back() - waypoints.front()).norm() < 1e-6) waypoints.pop_back();
    waypoints.push_back(waypoints[0]);
    waypoints.push_back(waypoints[0] + 0.3 * (waypoints[1] - waypoints[0]));
    scenario.route.type = "waypoints";
    scenario.route.waypoints = waypoints;
  }
  const RecordedDrive drive = RecordDrive(scenario);
  ASSERT_GT(drive.frames.size(), 100u);

  if (std::getenv("RETRACE_DEBUG")) spdlog::set_level(spdlog::level::debug);
  Teacher teacher(*drive.camera, TeachOptions(), nullptr);
  for (const Frame& frame : drive.frames) teacher.AddFrame(frame);
  teacher.Finish();
  const Map& map = teacher.map();
  std::cout << "loop: " << drive.frames.size() << " frames, " << map.nodes().size() << " key-images\n";
  EXPECT_TRUE(teacher.statistics().loop_closed);
  // Circular graph: as many arcs as nodes, the last one joining the last key-image to the first.
  EXPECT_EQ(map.arcs().size(), map.nodes().size());
  ASSERT_FALSE(map.arcs().empty());
  EXPECT_EQ(map.arcs().back().kind, "loop");
  EXPECT_EQ(map.arcs().back().from, map.nodes().back().id);
  const MapNode* closing = map.FindNode(map.arcs().back().to);
  EXPECT_LT(closing->id, 5) << "the loop closes onto one of the first key-images";
  // The loop arc's geometry is the true relative pose of the two key-images.
  const Rigid3d truth = drive.truth[closing->source_frame].world_from_cam.Inverse() *
                        drive.truth[map.nodes().back().source_frame].world_from_cam;
  EXPECT_LT(RotationErrorDeg(map.arcs().back().to_from_from.rotation, truth.rotation), 1.0);
  EXPECT_LT(AngleBetweenDeg(map.arcs().back().to_from_from.translation, truth.translation), 10.0);
}

TEST(TeachSim, FrameGapIsBridgedByMatching) {
  Scenario scenario = SmallTown();
  scenario.num_frames = 120;
  scenario.drive.max_speed = 6.0;
  const RecordedDrive drive = RecordDrive(scenario);
  ASSERT_EQ(drive.frames.size(), 120u);
  // 15 frames (about 9 m) missing in the middle of the drive, on a straight street: the first window after frame
  // 40 over which the camera turns by less than 2 degrees.
  size_t gap_begin = 40;
  while (gap_begin + 16 < drive.frames.size() &&
         RotationErrorDeg(drive.truth[gap_begin - 1].world_from_cam.rotation,
                          drive.truth[gap_begin + 15].world_from_cam.rotation) >
             2.0) {
    ++gap_begin;
  }
  ASSERT_LT(gap_begin + 16, drive.frames.size());
  const size_t gap_end = gap_begin + 15;
  if (std::getenv("RETRACE_DEBUG")) spdlog::set_level(spdlog::level::debug);
  Teacher teacher(*drive.camera, TeachOptions(), nullptr);
  for (const Frame& frame : drive.frames) {
    if (frame.index >= gap_begin && frame.index < gap_end) continue;
    teacher.AddFrame(frame);
  }
  teacher.Finish();
  const Map& map = teacher.map();
  EXPECT_GE(teacher.statistics().gaps_recovered, 1);
  EXPECT_EQ(teacher.statistics().gaps_unrecovered, 0);
  EXPECT_EQ(map.arcs().size() + 1, map.nodes().size());
  EXPECT_EQ(ReachableNodes(map), map.nodes().size()) << "one connected graph";
  const auto gap_arc = std::find_if(map.arcs().begin(), map.arcs().end(), [](const MapArc& a) { return a.kind == "gap"; });
  ASSERT_NE(gap_arc, map.arcs().end());
  EXPECT_LT(map.FindNode(gap_arc->from)->source_frame, static_cast<int64_t>(gap_begin));
  EXPECT_GE(map.FindNode(gap_arc->to)->source_frame, static_cast<int64_t>(gap_end));
  const Rigid3d truth = drive.truth[map.FindNode(gap_arc->to)->source_frame].world_from_cam.Inverse() *
                        drive.truth[map.FindNode(gap_arc->from)->source_frame].world_from_cam;
  // The gap arc rests on a few dozen matches across 9 m of 320x240 images; it connects the graph but is much less
  // accurate than tracked arcs. Its error is reported; the check only rules out relating the wrong places.
  const double rotation_error = RotationErrorDeg(gap_arc->to_from_from.rotation, truth.rotation);
  const double direction_error = AngleBetweenDeg(gap_arc->to_from_from.translation, truth.translation);
  std::cout << "gap arc " << gap_arc->id << ": " << gap_arc->num_features() << " features, rotation error "
            << rotation_error << " deg, translation direction error " << direction_error << " deg\n";
  EXPECT_LT(rotation_error, 10.0);
  EXPECT_LT(direction_error, 45.0);
}

// Arcs in turns against arcs on straights: their lengths (metres) and σ_p (px).
struct TurnStatistics {
  std::vector<double> turn_lengths, straight_lengths, turn_sigma, straight_sigma;
};

TurnStatistics TeachAndSplitByTurns(const RecordedDrive& drive, const TeachOptions& options) {
  Teacher teacher(*drive.camera, options, nullptr);
  for (const Frame& frame : drive.frames) teacher.AddFrame(frame);
  teacher.Finish();
  const Map& map = teacher.map();
  // Each arc's difficulty: how much the camera turns per metre along it (ground truth); turns versus straights.
  TurnStatistics stats;
  for (const MapArc& arc : map.arcs()) {
    const Rigid3d& a = drive.truth[map.FindNode(arc.from)->source_frame].world_from_cam;
    const Rigid3d& b = drive.truth[map.FindNode(arc.to)->source_frame].world_from_cam;
    const double metres = (b.translation - a.translation).norm();
    const double degrees = RotationErrorDeg(a.rotation, b.rotation);
    if (degrees / std::max(metres, 0.1) > 2.0) {
      stats.turn_lengths.push_back(metres);
      stats.turn_sigma.push_back(arc.sigma_p);
    } else if (degrees / std::max(metres, 0.1) < 0.3) {
      stats.straight_lengths.push_back(metres);
      stats.straight_sigma.push_back(arc.sigma_p);
    }
  }
  std::cout << map.nodes().size() << " key-images (min_features_fraction " << options.min_features_fraction
            << "); arcs in turns: " << stats.turn_lengths.size() << ", mean length " << Mean(stats.turn_lengths)
            << " m, mean sigma_p " << Mean(stats.turn_sigma) << " px; on straights: " << stats.straight_lengths.size()
            << ", mean length " << Mean(stats.straight_lengths) << " m, mean sigma_p " << Mean(stats.straight_sigma)
            << " px\n";
  return stats;
}

// Every arc's geometry against the true relative pose of its key-images. In the first 40 frames of the drive of
// seed 5 the random samples alone settled on a wrong motion for the arc of frames 24-27 (rotation 9.9 degrees,
// translation direction 46 degrees off, with a sigma_p of 0.23 px); each W(K, f) is now guided by the previous
// frame's.
TEST(TeachSim, EveryArcAgreesWithGroundTruth) {
  Scenario scenario;
  scenario.seed = 5;  // as `retrace sim render --seed 5`
  scenario.town.seed = 5;
  scenario.drive.wobble_seed = 5;
  scenario.num_frames = 40;
  const RecordedDrive drive = RecordDrive(scenario);
  Teacher teacher(*drive.camera, TeachOptions(), nullptr);
  for (const Frame& frame : drive.frames) teacher.AddFrame(frame);
  teacher.Finish();
  const Map& map = teacher.map();
  ASSERT_GE(map.arcs().size(), 5u);
  for (const MapArc& arc : map.arcs()) {
    const Rigid3d& a = drive.truth[map.FindNode(arc.from)->source_frame].world_from_cam;
    const Rigid3d& b = drive.truth[map.FindNode(arc.to)->source_frame].world_from_cam;
    const Rigid3d truth = b.Inverse() * a;
    const double rotation_error = RotationErrorDeg(arc.to_from_from.rotation, truth.rotation);
    const double direction_error = AngleBetweenDeg(arc.to_from_from.translation, truth.translation);
    EXPECT_LT(rotation_error, 1.0) << "arc " << arc.id << " (frames " << map.FindNode(arc.from)->source_frame << "-"
                                   << map.FindNode(arc.to)->source_frame << ")";
    EXPECT_LT(direction_error, 10.0) << "arc " << arc.id;
  }
}

TEST(TeachSim, KeyImagesAreDenserInTurns) {
  Scenario scenario = SmallTown();
  scenario.route.segments = 6;
  scenario.num_frames = 260;
  const RecordedDrive drive = RecordDrive(scenario);
  if (std::getenv("RETRACE_DEBUG")) spdlog::set_level(spdlog::level::debug);
  // The paper's rule (n = 50 alone): harder parts of the route get denser key-images and geometries of lower
  // quality (design §5).
  TeachOptions paper;
  paper.min_features_fraction = 0.0;
  const TurnStatistics by_paper = TeachAndSplitByTurns(drive, paper);
  ASSERT_GE(by_paper.turn_lengths.size(), 2u);
  ASSERT_GE(by_paper.straight_lengths.size(), 2u);
  EXPECT_LT(Mean(by_paper.turn_lengths), Mean(by_paper.straight_lengths));
  EXPECT_GT(Mean(by_paper.turn_sigma), Mean(by_paper.straight_sigma));
  // The default also keeps a fraction of the features tracked from each key-image (denser key-images everywhere,
  // where the feature count rather than σ_p ends most arcs): still denser in turns.
  const TurnStatistics by_default = TeachAndSplitByTurns(drive, TeachOptions());
  ASSERT_GE(by_default.turn_lengths.size(), 2u);
  ASSERT_GE(by_default.straight_lengths.size(), 2u);
  EXPECT_LT(Mean(by_default.turn_lengths), Mean(by_default.straight_lengths));
  EXPECT_GT(by_default.turn_lengths.size() + by_default.straight_lengths.size(),
            by_paper.turn_lengths.size() + by_paper.straight_lengths.size());
}

}  // namespace
}  // namespace retrace
