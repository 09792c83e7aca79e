// Several drives in one map (Booij 2007 §B.2, issue 15): a drive appended to a map is linked to it by join arcs
// where the two see the same place, and nowhere else. Checked against the simulator's ground truth in the town
// frame (each recorded drive has its own world frame: the camera at its start).

#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

#include "retrace/sim/recording.h"
#include "retrace/sim/simulator.h"
#include "retrace/teach/teacher.h"

namespace retrace {
namespace {

struct TownDrive {
  RecordedDrive drive;
  std::vector<Rigid3d> town_from_cam;  // ground truth of every frame in the town frame
  TownLayout layout;
};

// A drive through the listed junctions (route type "junctions") of a town of 3 x 2 blocks without moving
// occluders, at 320x240.
TownDrive DriveThrough(uint64_t seed, const std::vector<std::array<int, 2>>& junctions,
                       const std::string& camera_model = "perspective") {
  Scenario scenario;
  scenario.seed = seed;
  scenario.town.seed = seed;
  scenario.drive.wobble_seed = seed;
  scenario.town.blocks_x = 3;
  scenario.town.blocks_y = 2;
  scenario.town.num_pedestrians = 0;
  scenario.town.num_moving_cars = 0;
  scenario.camera.model = camera_model;
  scenario.camera.width = camera_model == "equirectangular" ? 640 : 320;
  scenario.camera.height = camera_model == "equirectangular" ? 320 : 240;
  scenario.route.type = "junctions";
  scenario.route.junctions = junctions;
  TownDrive result;
  result.drive = RecordDrive(scenario);
  const Simulator simulator(scenario);
  const Rigid3d town_from_world = simulator.town_from_world();
  result.layout = simulator.layout();
  for (const TimedPose& pose : result.drive.truth) result.town_from_cam.push_back(town_from_world * pose.world_from_cam);
  return result;
}

Map TeachDrive(const TownDrive& town_drive, const Map* existing, TeachStatistics* statistics) {
  if (std::getenv("RETRACE_DEBUG")) spdlog::set_level(spdlog::level::debug);
  Teacher teacher(*town_drive.drive.camera, TeachOptions(), nullptr);
  if (existing != nullptr) teacher.AppendTo(*existing);
  for (const Frame& frame : town_drive.drive.frames) teacher.AddFrame(frame);
  teacher.Finish();
  if (statistics != nullptr) *statistics = teacher.statistics();
  return teacher.map();
}

// Why a join A -> B is false against ground truth, or "" when it is true: the two key-images are far apart or look
// in directions too different to see one place (unless the camera is panoramic), or the arc's rotation or (unless the true baseline is tiny)
// translation direction disagrees with their true relative pose (the standard of teacher_sim_test's links).
std::string FalseJoinReason(const MapArc& arc, const Rigid3d& town_from_a, const Rigid3d& town_from_b,
                            bool panoramic) {
  const Rigid3d true_b_from_a = town_from_b.Inverse() * town_from_a;
  const double metres = true_b_from_a.translation.norm();
  const double views_deg = AngleBetweenDeg(town_from_a.rotation.col(2), town_from_b.rotation.col(2));
  const double rotation_deg = RotationErrorDeg(arc.to_from_from.rotation, true_b_from_a.rotation);
  const double direction_deg = AngleBetweenDeg(arc.to_from_from.translation, true_b_from_a.translation);
  std::ostringstream reason;
  if (metres > 30.0) reason << "key-images " << metres << " m apart; ";
  if (!panoramic && views_deg > 60.0) reason << "views " << views_deg << " deg apart; ";
  if (rotation_deg > 5.0) reason << "rotation " << rotation_deg << " deg off; ";
  if (metres > 1.0 && direction_deg > 10.0) reason << "translation direction " << direction_deg << " deg off; ";
  return reason.str();
}

struct JoinCheck {
  int joins = 0;
  std::vector<std::string> false_joins;
  std::vector<double> similarities;
  std::vector<double> distances_m;  // true distance between the two key-images of each join
  std::vector<double> lengths_arcs;  // length of each join in units of the new drive's arc into A (0: unknown)
  std::vector<Vector2d> positions;   // true ground-plane position (town x, y) of each join's new key-image
};

JoinCheck CheckJoins(const Map& first, const TownDrive& first_drive, const Map& appended,
                     const TownDrive& appended_drive) {
  JoinCheck check;
  for (const MapArc& arc : appended.arcs()) {
    if (arc.kind != "join") continue;
    ++check.joins;
    const MapNode* a = appended.FindNode(arc.from);
    const MapNode* b = first.FindNode(arc.to);
    EXPECT_NE(a, nullptr);
    EXPECT_NE(b, nullptr);
    if (a == nullptr || b == nullptr) continue;
    EXPECT_EQ(a->route, 1);
    EXPECT_EQ(b->route, 0);
    const Rigid3d& town_from_a = appended_drive.town_from_cam[a->source_frame];
    const Rigid3d& town_from_b = first_drive.town_from_cam[b->source_frame];
    check.distances_m.push_back((town_from_a.translation - town_from_b.translation).norm());
    check.positions.push_back(town_from_a.translation.head<2>());
    EXPECT_TRUE(arc.similarity.has_value());
    if (arc.similarity) check.similarities.push_back(*arc.similarity);
    double length = 0.0;
    for (const NodeScale& scale : appended.scales()) {
      if (scale.arc_out == arc.id) length = scale.scale;
    }
    check.lengths_arcs.push_back(length);
    // Full geometry: unit translation, 3D points.
    EXPECT_NEAR(arc.to_from_from.translation.norm(), 1.0, 1e-9);
    EXPECT_GT(arc.num_features(), 0u);
    const bool panoramic = appended_drive.drive.camera->model_name() == "equirectangular";
    const std::string reason = FalseJoinReason(arc, town_from_a, town_from_b, panoramic);
    if (!reason.empty()) {
      check.false_joins.push_back("join " + std::to_string(arc.from) + " (frame " + std::to_string(a->source_frame) +
                                  ") -> " + std::to_string(arc.to) + " (frame " + std::to_string(b->source_frame) +
                                  "): " + reason);
    }
  }
  return check;
}

std::string Describe(const JoinCheck& check) {
  std::ostringstream out;
  out << check.joins << " joins;";
  for (size_t i = 0; i < check.similarities.size(); ++i) {
    out << " S=" << check.similarities[i] << " at " << check.distances_m[i] << " m (" << check.lengths_arcs[i]
        << " arcs);";
  }
  for (const std::string& f : check.false_joins) out << "\n  FALSE " << f;
  return out.str();
}

// Two routes that share a street in the same direction: route 0 drives east along the southern street and turns
// north; route 1 comes from the north, turns east onto the same street and goes on straight. They are joined where
// they share the street, and only truly.
TEST(TeacherJoinTest, OverlappingRoutesAreJoinedWhereTheyShareAStreet) {
  const TownDrive route0 = DriveThrough(3, {{{0, 0}}, {{1, 0}}, {{2, 0}}, {{2, 1}}});
  const TownDrive route1 = DriveThrough(3, {{{1, 1}}, {{1, 0}}, {{2, 0}}, {{3, 0}}});
  const Map map0 = TeachDrive(route0, nullptr, nullptr);
  TeachStatistics statistics;
  const Map map1 = TeachDrive(route1, &map0, &statistics);
  ASSERT_FALSE(map1.nodes().empty());
  // Ids continue after the map's; the route number is the next one.
  EXPECT_GT(map1.nodes().front().id, map0.nodes().back().id);
  for (const MapNode& node : map1.nodes()) EXPECT_EQ(node.route, 1);
  for (const MapArc& arc : map0.arcs()) {
    ASSERT_TRUE(arc.similarity.has_value()) << "arc " << arc.id;
    EXPECT_GT(*arc.similarity, 0.0);
    EXPECT_LE(*arc.similarity, 1.0);
  }
  const JoinCheck check = CheckJoins(map0, route0, map1, route1);
  spdlog::info("overlapping routes: {} key-images + {}: {}", map0.nodes().size(), map1.nodes().size(),
               Describe(check));
  EXPECT_EQ(check.joins, statistics.joins);
  EXPECT_GE(check.joins, 3) << Describe(check);
  EXPECT_TRUE(check.false_joins.empty()) << Describe(check);
  for (const double s : check.similarities) EXPECT_GE(s, TeachOptions().min_join_similarity);
}

// The town of look-alike facades and zebra crossings (seed 11, teacher_sim_test): two drives along parallel streets
// a block apart never see the same place, and are not joined however alike their key-images look.
TEST(TeacherJoinTest, LookAlikeStreetsAreNotJoined) {
  const TownDrive route0 = DriveThrough(11, {{{0, 0}}, {{1, 0}}, {{2, 0}}, {{3, 0}}});
  const TownDrive route1 = DriveThrough(11, {{{0, 2}}, {{1, 2}}, {{2, 2}}, {{3, 2}}});
  const Map map0 = TeachDrive(route0, nullptr, nullptr);
  TeachStatistics statistics;
  const Map map1 = TeachDrive(route1, &map0, &statistics);
  const JoinCheck check = CheckJoins(map0, route0, map1, route1);
  int rejected = 0;
  for (const RejectedLink& link : statistics.rejected_links) rejected += link.kind == "join";
  spdlog::info("look-alike streets: {} key-images + {}: {}; {} join candidates rejected by verification",
               map0.nodes().size(), map1.nodes().size(), Describe(check), rejected);
  EXPECT_TRUE(check.false_joins.empty()) << Describe(check);
  EXPECT_EQ(check.joins, 0) << Describe(check);
}

// Two routes that cross at a right angle, seen through a panoramic camera (Booij's setting): route 0 drives east
// through the junction (1, 1), route 1 north through it. The two drives see the crossing from every side, and are
// joined there.
TEST(TeacherJoinTest, CrossingRoutesArePanoramicallyJoinedAtTheCrossing) {
  const TownDrive route0 = DriveThrough(5, {{{0, 1}}, {{1, 1}}, {{2, 1}}}, "equirectangular");
  const TownDrive route1 = DriveThrough(5, {{{1, 0}}, {{1, 1}}, {{1, 2}}}, "equirectangular");
  const Map map0 = TeachDrive(route0, nullptr, nullptr);
  TeachStatistics statistics;
  const Map map1 = TeachDrive(route1, &map0, &statistics);
  const JoinCheck check = CheckJoins(map0, route0, map1, route1);
  spdlog::info("crossing routes (panoramic): {} key-images + {}: {}", map0.nodes().size(), map1.nodes().size(),
               Describe(check));
  EXPECT_TRUE(check.false_joins.empty()) << Describe(check);
  EXPECT_GE(check.joins, 1) << Describe(check);
  // At the crossing: within 15 m of the junction (lanes 2 m off the centre lines, joins up to a few metres long).
  const Vector2d crossing = route0.layout.Junction(1, 1);
  for (const Vector2d& p : check.positions) EXPECT_LT((p - crossing).norm(), 15.0) << Describe(check);
}

}  // namespace
}  // namespace retrace
