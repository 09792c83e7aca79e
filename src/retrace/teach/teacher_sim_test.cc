// Teach in the simulator, where ground truth is exact: loop closing, gap recovery, links onto look-alike places,
// key-image density.

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <map>
#include <sstream>
#include <string>
#include <vector>

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

// Why a link between two key-images is false against ground truth, or "" when it is true (issue 13): the two
// key-images are far apart or look in directions too different to see the same place, or the link's rotation or
// (unless the true baseline is tiny) translation direction disagrees with their true relative pose.
std::string FalseLinkReason(const Map& map, const MapArc& arc, const std::vector<TimedPose>& truth) {
  const Rigid3d& from = truth[map.FindNode(arc.from)->source_frame].world_from_cam;
  const Rigid3d& to = truth[map.FindNode(arc.to)->source_frame].world_from_cam;
  const Rigid3d true_to_from_from = to.Inverse() * from;
  const double metres = true_to_from_from.translation.norm();
  const double views_deg = AngleBetweenDeg(from.rotation.col(2), to.rotation.col(2));
  const double rotation_deg = RotationErrorDeg(arc.to_from_from.rotation, true_to_from_from.rotation);
  const double direction_deg = AngleBetweenDeg(arc.to_from_from.translation, true_to_from_from.translation);
  std::ostringstream reason;
  if (metres > 30.0) reason << "key-images " << metres << " m apart; ";
  if (views_deg > 60.0) reason << "views " << views_deg << " deg apart; ";
  if (rotation_deg > 5.0) reason << "rotation " << rotation_deg << " deg off; ";
  if (metres > 1.0 && direction_deg > 10.0) reason << "translation direction " << direction_deg << " deg off; ";
  return reason.str();
}

// The false ones among the links made by matching (loop and gap arcs), described; `links` counts all of them.
std::vector<std::string> FalseLinks(const Map& map, const std::vector<TimedPose>& truth, int* links = nullptr) {
  std::vector<std::string> false_links;
  if (links != nullptr) *links = 0;
  for (const MapArc& arc : map.arcs()) {
    if (arc.kind != "loop" && arc.kind != "gap") continue;
    if (links != nullptr) ++*links;
    const std::string reason = FalseLinkReason(map, arc, truth);
    if (reason.empty()) continue;
    std::ostringstream description;
    description << arc.kind << " arc " << arc.id << " from key-image " << arc.from << " (frame "
                << map.FindNode(arc.from)->source_frame << ") to " << arc.to << " (frame "
                << map.FindNode(arc.to)->source_frame << "), " << arc.num_features() << " features: " << reason;
    false_links.push_back(description.str());
  }
  return false_links;
}

std::string Join(const std::vector<std::string>& lines) {
  std::string joined;
  for (const std::string& line : lines) joined += line + "\n";
  return joined;
}

// The town of look-alike facades and zebra crossings of issue 13, as `retrace sim render --seed 11 --frames 300
// --width 320 --height 240`: its last frame (at a crossing) matches frame 6 (at another crossing, 151 m away).
// Rendered once for the tests that use it.
const RecordedDrive& LookAlikeTown() {
  static const RecordedDrive drive = [] {
    Scenario scenario;
    scenario.seed = 11;
    scenario.town.seed = 11;
    scenario.drive.wobble_seed = 11;
    scenario.num_frames = 300;
    scenario.camera.width = 320;
    scenario.camera.height = 240;
    return RecordDrive(scenario);
  }();
  return drive;
}

struct Taught {
  Map map;
  TeachStatistics statistics;
};

// Teaches the given frames of the drive, in this order (each keeps its frame number as source index).
Taught Teach(const RecordedDrive& drive, const std::vector<size_t>& frames, const TeachOptions& options) {
  Teacher teacher(*drive.camera, options, nullptr);
  for (size_t i = 0; i < frames.size(); ++i) {
    Frame frame = drive.frames[frames[i]];
    frame.index = i;
    teacher.AddFrame(frame);
  }
  teacher.Finish();
  return {teacher.map(), teacher.statistics()};
}

std::vector<size_t> FrameRange(size_t first, size_t last) {
  std::vector<size_t> frames;
  for (size_t f = first; f <= last; ++f) frames.push_back(f);
  return frames;
}

void PrintRejected(const TeachStatistics& stats) {
  for (const RejectedLink& r : stats.rejected_links) {
    std::cout << "rejected " << r.kind << " link " << r.from << " (frame " << r.from_frame << ") -> " << r.to
              << " (frame " << r.to_frame << "): " << r.inliers << " inliers, " << r.trackable
              << " trackable, sigma_p " << r.sigma_p << " px: " << r.reason << "\n";
  }
}

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
  const double rotation_error = RotationErrorDeg(map.arcs().back().to_from_from.rotation, truth.rotation);
  const double direction_error = AngleBetweenDeg(map.arcs().back().to_from_from.translation, truth.translation);
  std::cout << "loop arc " << map.arcs().back().from << " -> " << closing->id << ": rotation error " << rotation_error
            << " deg, translation direction error " << direction_error << " deg, true baseline "
            << truth.translation.norm() << " m\n";
  EXPECT_LT(rotation_error, 1.0);
  EXPECT_LT(direction_error, 10.0);
  int links = 0;
  EXPECT_EQ(Join(FalseLinks(map, drive.truth, &links)), "");
  EXPECT_EQ(links, 1);
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

// The first 30 frames of that drive, a short straight: the last key-image matches the ones the drive passed a few
// metres before (the build before this test closed a loop onto one of them). A loop link goes forward
// (LinkDirectionOfTravel); none is closed, and the backward candidate is named in teach's summary.
TEST(TeachSim, AShortDriveClosesNoLoopBackwards) {
  const RecordedDrive& drive = LookAlikeTown();
  const Taught taught = Teach(drive, FrameRange(0, 29), TeachOptions());
  PrintRejected(taught.statistics);
  ASSERT_GE(taught.map.nodes().size(), 3u);
  EXPECT_FALSE(taught.statistics.loop_closed);
  EXPECT_EQ(taught.map.arcs().size() + 1, taught.map.nodes().size()) << "a linear graph";
  const std::vector<RejectedLink>& rejected = taught.statistics.rejected_links;
  EXPECT_TRUE(std::any_of(rejected.begin(), rejected.end(), [](const RejectedLink& link) {
    return link.kind == "loop" && link.reason.find("goes backwards") != std::string::npos;
  }));
}

TEST(TeachSim, LookAlikeCrossingDoesNotCloseTheLoop) {
  const RecordedDrive& drive = LookAlikeTown();
  ASSERT_EQ(drive.frames.size(), 300u);
  if (std::getenv("RETRACE_DEBUG")) spdlog::set_level(spdlog::level::debug);
  // The premise: with one pair of images as evidence (verification off), the last key-image is linked to a
  // key-image at the other crossing.
  TeachOptions single_pair;
  single_pair.verify_links = false;
  single_pair.reject_planar_geometry = false;
  single_pair.reject_undetermined_direction = false;
  const Taught unverified = Teach(drive, FrameRange(0, 299), single_pair);
  ASSERT_TRUE(unverified.statistics.loop_closed);
  const std::vector<std::string> premise = FalseLinks(unverified.map, drive.truth);
  ASSERT_EQ(premise.size(), 1u);
  std::cout << "without verification: " << premise[0] << "\n";

  const Taught taught = Teach(drive, FrameRange(0, 299), TeachOptions());
  const TeachStatistics& stats = taught.statistics;
  PrintRejected(stats);
  EXPECT_EQ(Join(FalseLinks(taught.map, drive.truth)), "");
  EXPECT_FALSE(stats.loop_closed);
  EXPECT_EQ(taught.map.arcs().size() + 1, taught.map.nodes().size()) << "a linear graph";
  // The candidate is reported, with its reason: its matches lie on the zebra crossing, whose other motion fits them
  // alike (41 of 50 inliers on that plane, TeachOptions::reject_planar_geometry), or, without that test, the
  // key-image after its target does not relate to the last one.
  ASSERT_EQ(stats.rejected_links.size(), 1u);
  const RejectedLink& rejected = stats.rejected_links[0];
  EXPECT_EQ(rejected.kind, "loop");
  EXPECT_EQ(rejected.from, taught.map.nodes().back().id);
  EXPECT_EQ(rejected.from_frame, 299);
  EXPECT_LT(rejected.to_frame, 20);
  EXPECT_GE(rejected.inliers, TeachOptions().min_loop_inliers) << "its own geometry passed the single-pair test";
  EXPECT_TRUE(rejected.reason.find("one plane") != std::string::npos ||
              rejected.reason.find("after") != std::string::npos)
      << rejected.reason;
}

// A recording that resumes elsewhere: the frames before the last crossing of the look-alike town, then the drive
// from its frame 6, at the other crossing. The frame after the jump matches the key-image before it (as the loop
// candidate above does); the frames tracked after it do not, and the map must stay disconnected there.
TEST(TeachSim, GapOntoALookAlikePlaceStaysDisconnected) {
  const RecordedDrive& drive = LookAlikeTown();
  std::vector<size_t> frames = FrameRange(288, 299);
  for (const size_t f : FrameRange(6, 24)) frames.push_back(f);
  if (std::getenv("RETRACE_DEBUG")) spdlog::set_level(spdlog::level::debug);
  TeachOptions options;
  options.close_loop = false;
  TeachOptions single_pair = options;
  single_pair.verify_links = false;
  single_pair.reject_planar_geometry = false;
  single_pair.reject_undetermined_direction = false;
  const Taught unverified = Teach(drive, frames, single_pair);
  ASSERT_EQ(unverified.statistics.gaps_recovered, 1) << "the premise: one pair of images links across the jump";
  const std::vector<std::string> premise = FalseLinks(unverified.map, drive.truth);
  ASSERT_EQ(premise.size(), 1u) << "the premise: that link is false";
  std::cout << "without verification: " << premise[0] << "\n";

  const Taught taught = Teach(drive, frames, options);
  const TeachStatistics& stats = taught.statistics;
  PrintRejected(stats);
  EXPECT_EQ(Join(FalseLinks(taught.map, drive.truth)), "");
  EXPECT_EQ(stats.gaps_recovered, 0);
  EXPECT_EQ(stats.gaps_unrecovered, 1);
  EXPECT_EQ(stats.key_images_by_reason[static_cast<int>(KeyImageReason::kDisconnected)], 1);
  EXPECT_EQ(stats.key_images_by_reason[static_cast<int>(KeyImageReason::kGap)], 0);
  EXPECT_EQ(taught.map.arcs().size() + 2, taught.map.nodes().size()) << "two linear pieces";
  EXPECT_LT(ReachableNodes(taught.map), taught.map.nodes().size()) << "disconnected";
  ASSERT_EQ(stats.rejected_links.size(), 1u);
  const RejectedLink& rejected = stats.rejected_links[0];
  EXPECT_EQ(rejected.kind, "gap");
  EXPECT_EQ(rejected.from_frame, 299);
  EXPECT_EQ(rejected.to_frame, 6);
  EXPECT_GE(rejected.inliers, TeachOptions().min_matched_inliers);
  EXPECT_FALSE(rejected.reason.empty());
}

// The same jump at a low frame rate: every 6th frame, where tracking fails between any two frames and every arc is a
// gap arc, confirmed by the key-image after it (K -> G by K matched with H, G -> H being a gap arc too). The link
// across the jump must be rejected, and the runs of gap arcs on either side of it must stay connected. The true gap
// arc into frame 299 loses its witness with the false one after it, and the last gap arc of the recording has none:
// both are rejected and reported too. Near the crossing, the gap arcs 275 -> 281 and 281 -> 287 rest on matches of
// which 38 of 62 and 48 of 63 lie on the zebra crossing, and the crossing's other motion fits them within 19 % and 7 %
// of the estimate's cost: the pairs do not determine the motion (TeachOptions::reject_planar_geometry), and the run
// before the jump is three pieces (263-275, with the arc 269 -> 275 lost with its witness, and 287-293).
TEST(TeachSim, RunOfGapArcsOntoALookAlikePlaceStaysDisconnected) {
  const RecordedDrive& drive = LookAlikeTown();
  std::vector<size_t> frames;
  for (size_t f = 263; f <= 299; f += 6) frames.push_back(f);
  for (size_t f = 6; f <= 48; f += 6) frames.push_back(f);
  if (std::getenv("RETRACE_DEBUG")) spdlog::set_level(spdlog::level::debug);
  TeachOptions options;
  options.close_loop = false;
  TeachOptions single_pair = options;
  single_pair.verify_links = false;
  single_pair.reject_planar_geometry = false;
  single_pair.reject_undetermined_direction = false;
  const Taught unverified = Teach(drive, frames, single_pair);
  ASSERT_EQ(unverified.map.arcs().size() + 1, unverified.map.nodes().size()) << "the premise: all frames linked";
  const std::vector<std::string> premise = FalseLinks(unverified.map, drive.truth);
  ASSERT_EQ(premise.size(), 1u) << "the premise: the link across the jump is false";
  std::cout << "without verification: " << premise[0] << "\n";

  const Taught taught = Teach(drive, frames, options);
  const Map& map = taught.map;
  PrintRejected(taught.statistics);
  int links = 0;
  EXPECT_EQ(Join(FalseLinks(map, drive.truth, &links)), "");
  EXPECT_GE(links, 8) << "the runs of gap arcs are confirmed (but where they rest on the crossing alone)";
  const auto jump = std::find_if(taught.statistics.rejected_links.begin(), taught.statistics.rejected_links.end(),
                                 [](const RejectedLink& r) { return r.from_frame == 299 && r.to_frame == 6; });
  ASSERT_NE(jump, taught.statistics.rejected_links.end()) << "the link across the jump is reported";
  EXPECT_EQ(jump->kind, "gap");
  // Which key-images are joined: each run is one piece, the two runs are not joined.
  std::map<int64_t, node_t> node_of_frame;
  for (const MapNode& node : map.nodes()) node_of_frame[node.source_frame] = node.id;
  std::map<node_t, node_t> piece;
  for (const MapNode& node : map.nodes()) piece[node.id] = node.id;
  const std::function<node_t(node_t)> root = [&](node_t n) {
    return piece[n] == n ? n : piece[n] = root(piece[n]);
  };
  for (const MapArc& arc : map.arcs()) piece[root(arc.from)] = root(arc.to);
  const auto joined = [&](int64_t a, int64_t b) { return root(node_of_frame.at(a)) == root(node_of_frame.at(b)); };
  EXPECT_TRUE(joined(263, 269));
  EXPECT_TRUE(joined(287, 293));
  EXPECT_TRUE(joined(6, 42));
  EXPECT_FALSE(joined(293, 6));
  EXPECT_FALSE(joined(299, 6));
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
