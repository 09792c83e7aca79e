#include "retrace/repeat/evaluation.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

namespace retrace {
namespace {

// A camera looking along `forward` (horizontal; the world's z axis up), x right and y down.
Matrix3d LookingAlong(const Vector3d& forward) {
  Matrix3d rotation;
  rotation.col(2) = forward.normalized();
  rotation.col(1) = Vector3d(0, 0, -1);
  rotation.col(0) = rotation.col(1).cross(rotation.col(2));
  return rotation;
}

// A straight route along x: key-images at frames 0, 10, 20, 30 (x = frame), arcs 0, 1, 2; the camera looks along x.
struct StraightRoute {
  Map map;
  std::vector<TimedPose> truth;
  StraightRoute() {
    for (int i = 0; i <= 40; ++i) {
      TimedPose pose;
      pose.timestamp = i;
      pose.world_from_cam.rotation = LookingAlong(Vector3d::UnitX());
      pose.world_from_cam.translation = Vector3d(i, 0.3 * (i % 2), 0);
      truth.push_back(pose);
    }
    for (int k = 0; k < 4; ++k) {
      MapNode node;
      node.id = k;
      node.source_frame = 10 * k;
      map.AddNode(node);
    }
    for (int k = 0; k < 3; ++k) {
      MapArc arc;
      arc.id = 10 + k;  // ids need not be positions
      arc.from = k;
      arc.to = k + 1;
      map.AddArc(arc);
    }
  }
};

TEST(RouteArcs, FollowsTheChain) {
  const StraightRoute route;
  EXPECT_EQ(RouteArcs(route.map), (std::vector<arc_t>{10, 11, 12}));
}

// A map teach left disconnected: key-images 0 .. 7 (frames 0, 10, ..., 70), arcs 0 -> 1 -> 2 and 4 -> 5 -> 6, none
// at key-image 3 (teach could not verify the arcs around it) or 7. The later piece's arcs come first in the map (the
// teacher adds an arc over a gap only once confirmed) and the first arc of a piece need not have the lowest id.
struct TwoPieceRoute {
  Map map;
  std::vector<TimedPose> truth;  // frame i at x = i, the camera looking along x
  TwoPieceRoute() {
    for (int i = 0; i <= 80; ++i) {
      TimedPose pose;
      pose.timestamp = i;
      pose.world_from_cam.rotation = LookingAlong(Vector3d::UnitX());
      pose.world_from_cam.translation = Vector3d(i, 0.3 * (i % 2), 0);
      truth.push_back(pose);
    }
    for (int k = 0; k < 8; ++k) {
      MapNode node;
      node.id = k;
      node.source_frame = 10 * k;
      map.AddNode(node);
    }
    for (const auto& [id, from] : std::vector<std::pair<arc_t, node_t>>{{21, 5}, {22, 4}, {10, 0}, {11, 1}}) {
      MapArc arc;
      arc.id = id;
      arc.from = from;
      arc.to = from + 1;
      arc.kind = id == 22 ? "gap" : "tracking";
      map.AddArc(arc);
    }
  }
};

TEST(RouteArcs, TakesThePiecesInTeachOrder) {
  TwoPieceRoute route;
  EXPECT_EQ(RouteArcs(route.map), (std::vector<arc_t>{10, 11, 22, 21}));
  // Closed onto key-image 1 from the last node of the route, 6, or from key-image 7 after it.
  for (const node_t last : {6, 7}) {
    TwoPieceRoute circular;
    MapArc loop;
    loop.id = 30;
    loop.from = last;
    loop.to = 1;
    loop.kind = "loop";
    circular.map.AddArc(loop);
    EXPECT_EQ(RouteArcs(circular.map), (std::vector<arc_t>{10, 11, 22, 21, 30})) << "loop from key-image " << last;
  }
}

// The probes go back and forth along the route; the camera, looking along +x, drives them forward and reversing.
TEST(EvaluateTopological, CountsCorrectToleratedWrongAndLost) {
  const StraightRoute route;
  const std::vector<RepeatRecord> records = {
      {15, true, 11},              // correct
      {15, true, 10},              // wrong by one (mid-arc)
      {5, true, 12},               // wrong by two
      {11, true, 10},              // near node 1: arc 0 tolerated
      {13, true, 10},              // not near a node any more: wrong
      {29, true, 12},              // near node 3: the next arc tolerated
      {25, false, kInvalidArcId},  // lost
      {38, true, 12},              // beyond the last key-image: last arc
  };
  const TopologicalEvaluation e = EvaluateTopological(route.map, route.truth, route.truth, records);
  EXPECT_EQ(e.frames, 8);
  EXPECT_EQ(e.correct, 4);
  EXPECT_EQ(e.wrong, 3);
  EXPECT_EQ(e.wrong_by_two, 1);
  EXPECT_EQ(e.lost, 1);
  EXPECT_TRUE(e.per_frame[0].correct);
  EXPECT_FALSE(e.per_frame[1].correct);
  EXPECT_EQ(e.per_frame[2].error, 2);
  EXPECT_TRUE(e.per_frame[3].correct);
  EXPECT_FALSE(e.per_frame[4].correct);
  EXPECT_TRUE(e.per_frame[5].correct);
  EXPECT_TRUE(e.per_frame[6].lost);
  EXPECT_TRUE(e.per_frame[7].correct);
  EXPECT_NEAR(e.FractionCorrect(), 0.5, 1e-12);
  // The true position on the reported arc: frame 15 is halfway along arc 11 (x 10..20), 1.5 arcs along arc 10, 1.5
  // arcs before arc 12; none when lost.
  EXPECT_NEAR(e.per_frame[0].true_position_on_arc, 0.5, 1e-12);
  EXPECT_NEAR(e.per_frame[1].true_position_on_arc, 1.5, 1e-12);
  EXPECT_NEAR(e.per_frame[2].true_position_on_arc, -1.5, 1e-12);
  EXPECT_TRUE(std::isnan(e.per_frame[6].true_position_on_arc));
}

// Between the two pieces (x = 20 .. 40, through key-image 3 at x = 30) the true arc is none; the arcs on either side
// (route indices 1 and 2) are tolerated, any other is wrong; steps along the route count the stretch as one.
TEST(EvaluateTopological, StretchBetweenPiecesHasNoArc) {
  const TwoPieceRoute route;
  const std::vector<RepeatRecord> records = {
      {15, true, 11},              // on the first piece: correct
      {25, true, 11},              // in the stretch, on the arc before it: tolerated
      {35, true, 22},              // in the stretch, on the arc after it: tolerated
      {33, true, 10},              // in the stretch, two steps away: wrong
      {37, true, 21},              // in the stretch, two steps the other way: wrong
      {30, false, kInvalidArcId},  // lost
      {45, true, 22},              // on the second piece: correct (was: the first piece's last arc, wrong)
      {55, true, 21},              // correct
      {41, true, 11},              // near key-image 4 but across the stretch: wrong
      {19, true, 22},              // near key-image 2, across the stretch: wrong
      {55, true, 10},              // four steps away (arc 10, 11, the stretch, 22, 21)
  };
  const TopologicalEvaluation e = EvaluateTopological(route.map, route.truth, route.truth, records);
  ASSERT_EQ(e.frames, 11);
  EXPECT_EQ(e.correct, 5);
  EXPECT_EQ(e.lost, 1);
  EXPECT_EQ(e.wrong, 5);
  EXPECT_EQ(e.wrong_by_two, 5);
  const std::vector<int> true_arc = {1, -1, -1, -1, -1, -1, 2, 3, 2, 1, 3};
  const std::vector<bool> correct = {true, true, true, false, false, false, true, true, false, false, false};
  const std::vector<int> error = {0, 1, 1, 2, 2, 0, 0, 0, 2, 2, 4};
  for (size_t i = 0; i < e.per_frame.size(); ++i) {
    EXPECT_EQ(e.per_frame[i].true_arc_index, true_arc[i]) << "record " << i;
    EXPECT_EQ(e.per_frame[i].correct, correct[i]) << "record " << i;
    EXPECT_EQ(e.per_frame[i].error, error[i]) << "record " << i;
  }
  EXPECT_EQ(e.per_frame[1].tolerated_arc_index, 1);
  EXPECT_EQ(e.per_frame[1].tolerated_after_arc_index, 2);
  EXPECT_TRUE(e.per_frame[5].lost);
  EXPECT_EQ(e.per_frame[8].tolerated_arc_index, -1);
  EXPECT_EQ(e.per_frame[9].tolerated_arc_index, -1);
  // A frame reported on an arc that is not on the route is off by the whole route: four arcs and the stretch.
  const TopologicalEvaluation off = EvaluateTopological(route.map, route.truth, route.truth, {{25, true, 99}});
  EXPECT_FALSE(off.per_frame[0].correct);
  EXPECT_EQ(off.per_frame[0].error, 5);
}

TEST(EvaluateTopological, MissingPoseIsAnError) {
  const StraightRoute route;
  EXPECT_THROW(EvaluateTopological(route.map, route.truth, route.truth, {{100, true, 10}}), std::invalid_argument);
}

// Routes that cross or retrace themselves (design §9: the truth follows the direction of travel and the order along
// the drive). A drive follows a polyline of waypoints in the ground plane (z = 0), the camera looking the way it
// drives; the point at arc length s is `offset(s)` to the right of the polyline (negative: left). Waypoints are 10 m
// apart along the route where it turns, so the key-images of the teach drive (one every 10 m) sit on the corners.
struct Waypoints {
  std::vector<Vector2d> points;

  TimedPose At(double s, double offset) const {
    size_t i = 0;
    for (; i + 2 < points.size(); ++i) {
      const double leg = (points[i + 1] - points[i]).norm();
      if (s <= leg) break;
      s -= leg;
    }
    const Vector2d heading = (points[i + 1] - points[i]).normalized();
    const Vector2d right(heading.y(), -heading.x());
    const Vector2d p = points[i] + s * heading + offset * right;
    TimedPose pose;
    pose.timestamp = s;
    pose.world_from_cam.rotation = LookingAlong(Vector3d(heading.x(), heading.y(), 0));
    pose.world_from_cam.translation = Vector3d(p.x(), p.y(), 0);
    return pose;
  }
};

constexpr double kKeySpacing = 10.0;  // metres between key-images of the teach drive (one frame per metre)
constexpr arc_t kFirstArcId = 100;

// Teach: frames at s = 0, 1, ..., length; key-images every 10 frames and at the last frame (as the teacher does);
// arc k (id 100 + k) from key-image k to k + 1. With `loop_to` >= 0 the route is circular: a loop-closing arc from
// the last key-image to key-image `loop_to`.
struct TaughtRoute {
  Map map;
  std::vector<TimedPose> truth;
  int num_arcs = 0;  // without the loop-closing one

  TaughtRoute(const Waypoints& route, int length, int loop_to = -1) {
    for (int i = 0; i <= length; ++i) truth.push_back(route.At(i, 0.0));
    std::vector<int> key_frames;
    for (int i = 0; i <= length; i += static_cast<int>(kKeySpacing)) key_frames.push_back(i);
    if (key_frames.back() != length) key_frames.push_back(length);
    for (size_t k = 0; k < key_frames.size(); ++k) {
      MapNode node;
      node.id = static_cast<node_t>(k);
      node.source_frame = key_frames[k];
      map.AddNode(node);
    }
    num_arcs = static_cast<int>(key_frames.size()) - 1;
    for (int k = 0; k < num_arcs; ++k) {
      MapArc arc;
      arc.id = kFirstArcId + k;
      arc.from = k;
      arc.to = k + 1;
      map.AddArc(arc);
    }
    if (loop_to >= 0) {
      MapArc arc;
      arc.id = kFirstArcId + num_arcs;
      arc.from = num_arcs;
      arc.to = loop_to;
      arc.kind = "loop";
      map.AddArc(arc);
    }
  }
};

// A repeat drive: frame i at arc length s[i] of the route, reporting `arc_index(s)` (the arc it is truly on).
struct RepeatDrive {
  std::vector<double> s;
  std::vector<TimedPose> truth;
  std::vector<RepeatRecord> records;

  RepeatDrive(const Waypoints& route, const std::vector<double>& at, const std::function<double(double)>& offset,
              const std::function<int(double)>& arc_index) {
    for (const double si : at) {
      records.push_back({truth.size(), true, kFirstArcId + arc_index(si)});
      s.push_back(si);
      truth.push_back(route.At(si, offset(si)));
    }
  }
};

std::vector<double> Every(double step, double first, double last) {
  std::vector<double> at;
  for (double s = first; s <= last + 1e-9; s += step) at.push_back(s);
  return at;
}

double OneMetreRight(double) { return 1.0; }

int ArcAt(double s) { return static_cast<int>(std::floor(s / kKeySpacing)); }

// Every frame on its true arc counts as correct, and mid-arc (away from the tolerance near the nodes) the true arc is
// exactly the one the frame was driven on.
void ExpectAllCorrect(const TopologicalEvaluation& e, const RepeatDrive& drive,
                      const std::function<int(double)>& arc_index) {
  ASSERT_EQ(e.per_frame.size(), drive.s.size());
  EXPECT_EQ(e.correct, e.frames);
  EXPECT_EQ(e.wrong_by_two, 0);
  for (size_t i = 0; i < drive.s.size(); ++i) {
    const double s = drive.s[i];
    EXPECT_TRUE(e.per_frame[i].correct) << "frame at s = " << s << ": true arc " << e.per_frame[i].true_arc_index
                                        << ", driven on " << arc_index(s);
    const double fraction = s / kKeySpacing - std::floor(s / kKeySpacing);
    if (fraction > 0.2 && fraction < 0.8) {
      EXPECT_EQ(e.per_frame[i].true_arc_index, arc_index(s)) << "s = " << s;
    }
  }
}

// A figure-8: north-east through the middle, round the top, south-east through the middle again; the two passes cross
// at (20, 15) at 74 degrees (less than 90: the heading alone cannot tell them apart), at s = 25 and s = 135.
//
//   (0,40) +<---------------+ (40,40)
//          |                ^
//   (0,30) +.              .+ (40,30)
//             `.        .'
//                `.  .'
//                  X (20,15)
//                .'  `.
//             .'        `.
//    (0,0) +'              `+ (40,0)
const Waypoints kFigureEight{{{0, 0}, {40, 30}, {40, 40}, {0, 40}, {0, 30}, {40, 0}}};
constexpr int kFigureEightLength = 160;

TEST(EvaluateTopological, SelfCrossingRouteFollowsTheDrive) {
  const TaughtRoute taught(kFigureEight, kFigureEightLength);
  EXPECT_EQ(taught.num_arcs, 16);
  // 1 m to the right of the taught path: near the crossing the other pass is nearer (the nearest segment was 11 arcs
  // off for 4 frames).
  const RepeatDrive drive(kFigureEight, Every(1.0, 0.5, 159.5), OneMetreRight, ArcAt);
  const TopologicalEvaluation e = EvaluateTopological(taught.map, taught.truth, drive.truth, drive.records);
  ExpectAllCorrect(e, drive, ArcAt);
}

TEST(EvaluateTopological, DroppedFramesAndStartInTheMiddle) {
  const TaughtRoute taught(kFigureEight, kFigureEightLength);
  // From just before the first crossing, every other frame, then nothing for 60 m (the top of the figure), then
  // every other frame over the second crossing to the end.
  std::vector<double> at = Every(2.0, 20.5, 38.5);
  for (const double s : Every(2.0, 100.5, 158.5)) at.push_back(s);
  const RepeatDrive drive(kFigureEight, at, OneMetreRight, ArcAt);
  const TopologicalEvaluation e = EvaluateTopological(taught.map, taught.truth, drive.truth, drive.records);
  ExpectAllCorrect(e, drive, ArcAt);
}

// A kidnapped start's frames: three frames over the second crossing, evaluated alone, lose the order along the drive
// and may be judged against the first pass, 11 arcs away; judged by the truth of the whole drive (IsCorrectEstimate)
// their true arc is right and an arc of the first pass wrong.
TEST(IsCorrectEstimate, TakesTheTruthOfTheWholeDrive) {
  const TaughtRoute taught(kFigureEight, kFigureEightLength);
  const RepeatDrive whole(kFigureEight, Every(1.0, 0.5, 159.5), OneMetreRight, ArcAt);
  std::vector<RepeatRecord> unlocalized = whole.records;
  for (RepeatRecord& r : unlocalized) r.localized = false;
  const TopologicalEvaluation truth = EvaluateTopological(taught.map, taught.truth, whole.truth, unlocalized);
  const std::vector<arc_t> route = RouteArcs(taught.map);
  ASSERT_EQ(truth.per_frame.size(), whole.s.size());
  for (const double s : {134.5, 135.5, 136.5}) {
    const size_t i = static_cast<size_t>(s);  // frame i is at s = i + 0.5
    EXPECT_TRUE(IsCorrectEstimate(truth.per_frame[i], route, kFirstArcId + ArcAt(s))) << "s = " << s;
    EXPECT_FALSE(IsCorrectEstimate(truth.per_frame[i], route, kFirstArcId + ArcAt(s - 110.0))) << "s = " << s;
    EXPECT_FALSE(IsCorrectEstimate(truth.per_frame[i], route, kInvalidArcId));
  }
  // The same three frames evaluated alone: the first pass is nearer (1 m to the right of the taught path near the
  // crossing), and nothing says which pass they belong to.
  const RepeatDrive alone(kFigureEight, {134.5, 135.5, 136.5}, OneMetreRight, ArcAt);
  const TopologicalEvaluation e = EvaluateTopological(taught.map, taught.truth, alone.truth, alone.records);
  int judged_right = 0;
  for (const FrameTruth& f : e.per_frame) judged_right += f.correct;
  EXPECT_LT(judged_right, 3) << "evaluated alone the crossing was judged right: the test no longer shows the need";
}

// A street driven east and back west in the other lane, 3 m to the north (a U-turn at x = 60). The repeat drives 2 m
// to the left of the taught path on both ways, nearer to the other lane than to its own, back on the taught path
// around the U-turn (a car cannot turn in 3 m with an offset of 2 m inside the turn).
//
//   (3,3) +<------------------------+ (60,3)
//                                   ^
//   (0,0) +------------------------>+ (60,0)
const Waypoints kOutAndBack{{{0, 0}, {60, 0}, {60, 3}, {3, 3}}};
constexpr int kOutAndBackLength = 120;

double LeftOfTheStreet(double s) { return -2.0 * std::clamp((std::abs(s - 61.5) - 4.0) / 4.0, 0.0, 1.0); }

TEST(EvaluateTopological, RouteRetracedInTheOppositeDirection) {
  const TaughtRoute taught(kOutAndBack, kOutAndBackLength);
  const RepeatDrive drive(kOutAndBack, Every(1.0, 0.5, 119.5), LeftOfTheStreet, ArcAt);
  const TopologicalEvaluation e = EvaluateTopological(taught.map, taught.truth, drive.truth, drive.records);
  ExpectAllCorrect(e, drive, ArcAt);

  // Starting on the way back, and a single frame on it: only the heading tells the lanes apart.
  const RepeatDrive back(kOutAndBack, Every(1.0, 80.5, 119.5), LeftOfTheStreet, ArcAt);
  ExpectAllCorrect(EvaluateTopological(taught.map, taught.truth, back.truth, back.records), back, ArcAt);
  const RepeatDrive one(kOutAndBack, {95.5}, LeftOfTheStreet, ArcAt);
  const TopologicalEvaluation single = EvaluateTopological(taught.map, taught.truth, one.truth, one.records);
  EXPECT_EQ(single.per_frame[0].true_arc_index, 9);
}

// Around a 40 m x 20 m block (120 m) and on along the first street; the teacher closes the loop from the last
// key-image onto key-image 1 (s = 10, where the drive passes again at s = 130). The repeat drives two laps: past the
// last key-image it is on the loop arc and then on arcs 1, 2, ... again, never on the first lap's arcs at the same
// place (from s = 120 on, the drive is where arcs 0 and 1 are).
const Waypoints kBlock{{{0, 0}, {40, 0}, {40, 20}, {0, 20}, {0, 0}, {40, 0}, {40, 20}, {0, 20}, {0, 0}}};

// The arc driven at s when the last key-image is at s = `last` (the loop arc between it and key-image 1 when the
// last key-image is before s = 130, where key-image 1 is).
std::function<int(double)> CircularArcs(int last, int num_arcs) {
  return [last, num_arcs](double s) {
    if (s < last) return std::min(ArcAt(s), num_arcs - 1);
    if (s < 130.0) return num_arcs;
    return ArcAt(s - 120.0);
  };
}

TEST(EvaluateTopological, CircularRouteGoesOnOverTheLoopArc) {
  // The last key-image where key-image 1 is, 3 m before it, and 6 m past it.
  for (const int last : {130, 127, 136}) {
    SCOPED_TRACE("last key-image at s = " + std::to_string(last));
    const TaughtRoute taught(kBlock, last, /*loop_to=*/1);
    std::vector<arc_t> expected_route;
    for (int k = 0; k <= taught.num_arcs; ++k) expected_route.push_back(kFirstArcId + k);
    EXPECT_EQ(RouteArcs(taught.map), expected_route) << "the route ends with the loop-closing arc";
    const auto arcs = CircularArcs(last, taught.num_arcs);
    const RepeatDrive drive(kBlock, Every(1.0, 0.5, 239.5), OneMetreRight, arcs);
    ExpectAllCorrect(EvaluateTopological(taught.map, taught.truth, drive.truth, drive.records), drive, arcs);
  }

  // Just past the last key-image the loop arc is tolerated; arc 12 reported on arc 1 of the second lap is two arcs
  // along the drive off (12, loop, 1), not eleven.
  const TaughtRoute taught(kBlock, 130, /*loop_to=*/1);
  const arc_t loop = kFirstArcId + 13;
  RepeatDrive probes(kBlock, {115.5, 125.5, 130.5, 135.5}, OneMetreRight, CircularArcs(130, 13));
  probes.records[2].arc = loop;
  probes.records[3].arc = kFirstArcId + 12;
  const TopologicalEvaluation p = EvaluateTopological(taught.map, taught.truth, probes.truth, probes.records);
  EXPECT_EQ(p.per_frame[1].true_arc_index, 12);
  EXPECT_EQ(p.per_frame[2].true_arc_index, 1);
  EXPECT_EQ(p.per_frame[2].estimated_arc_index, 13);
  EXPECT_TRUE(p.per_frame[2].correct);
  EXPECT_EQ(p.per_frame[3].true_arc_index, 1);
  EXPECT_FALSE(p.per_frame[3].correct);
  EXPECT_EQ(p.per_frame[3].error, 2);
}

// Near a node in a turn (design §9: ±1 near a node). A right-angle turn at key-image 2, (20, 0): east, then south;
// arcs of 10 m. Each probe is a single frame, the camera looking halfway round the turn (both arcs pass the heading
// test; the labels are the nearest segments).
const Waypoints kRightTurn{{{0, 0}, {20, 0}, {20, -20}}};

struct TurnProbe {
  Vector2d position;
  Vector2d heading;
  int reported;  // route index of the reported arc
};

FrameTruth JudgeInTurn(const TurnProbe& probe) {
  const TaughtRoute taught(kRightTurn, 40);
  TimedPose pose;
  pose.world_from_cam.rotation = LookingAlong(Vector3d(probe.heading.x(), probe.heading.y(), 0));
  pose.world_from_cam.translation = Vector3d(probe.position.x(), probe.position.y(), 0);
  const TopologicalEvaluation e =
      EvaluateTopological(taught.map, taught.truth, {pose}, {{0, true, kFirstArcId + probe.reported}});
  return e.per_frame.at(0);
}

TEST(EvaluateTopological, NearANodeInATurn) {
  const Vector2d halfway(1, -1);
  // 0.3 m before the node, 1 and 2 m inside the turn: the nearest segment is the arc after the node (south), on
  // which the frame projects at 0.1 and 0.2 of its length (2 m: beyond the projection rule); the arc before is
  // tolerated as the frame is abeam the node (0.5 m and 1.2 m from it along the route's direction there, less than
  // 0.15 x 10 m).
  for (const double inside : {1.0, 2.0}) {
    SCOPED_TRACE("inside " + std::to_string(inside));
    const FrameTruth t = JudgeInTurn({{19.7, -inside}, halfway, 1});
    EXPECT_EQ(t.true_arc_index, 2);
    EXPECT_EQ(t.tolerated_arc_index, 1);
    EXPECT_TRUE(t.correct);
  }
  // 0.3 m before the node, 1 and 2 m outside the turn: the arc after the node is tolerated, as the arc before is
  // when the labelling puts the frame after the node.
  for (const double outside : {1.0, 2.0}) {
    SCOPED_TRACE("outside " + std::to_string(outside));
    const FrameTruth t = JudgeInTurn({{19.7, outside}, halfway, 2});
    EXPECT_TRUE(t.correct);
    const FrameTruth after = JudgeInTurn({{20 + outside, -0.3}, halfway, 1});
    EXPECT_TRUE(after.correct);
  }
  // Half an arc before the node, 1.5 m to either side, looking east: not near the node.
  for (const double side : {-1.5, 1.5}) {
    SCOPED_TRACE("side " + std::to_string(side));
    const FrameTruth t = JudgeInTurn({{15, side}, {1, 0}, 2});
    EXPECT_EQ(t.true_arc_index, 1);
    EXPECT_EQ(t.tolerated_arc_index, -1);
    EXPECT_FALSE(t.correct);
  }
  // A hairpin (the U-turn of the street driven out and back, 157 degrees at key-image 6): the route's direction at
  // the node crosses both arcs, and a frame halfway along the arc before it, 1 m to the left, is 0.1 m abeam the node
  // but not near it.
  const TaughtRoute street(kOutAndBack, kOutAndBackLength);
  const RepeatDrive hairpin(kOutAndBack, {55.5}, LeftOfTheStreet, [](double) { return 6; });
  const TopologicalEvaluation h = EvaluateTopological(street.map, street.truth, hairpin.truth, hairpin.records);
  EXPECT_EQ(h.per_frame[0].true_arc_index, 5);
  EXPECT_FALSE(h.per_frame[0].correct);
}

// The route index of the arc driven at s when teach made no arcs between key-images `gap_from` and `gap_to` (they
// are `gap_to - gap_from` apart): -1 in that stretch, one index per missing arc less after it.
std::function<int(double)> WithoutArcs(const std::function<int(double)>& arc_at, int gap_from, int gap_to) {
  return [=](double s) {
    const int k = arc_at(s);
    return k < gap_from ? k : k < gap_to ? -1 : k - (gap_to - gap_from);
  };
}

// The figure-8 taught without arcs around its top-right corner (key-images 5, 6 and 7 at s = 50, 60, 70; key-image 6
// without arcs): the route is two pieces, the stretch between them turns through key-image 6. The drive reports the
// arc before the stretch and then the one after it; the crossings still follow the drive.
TEST(EvaluateTopological, SelfCrossingRouteInTwoPieces) {
  TaughtRoute taught(kFigureEight, kFigureEightLength);
  Map map;
  for (const MapNode& node : taught.map.nodes()) map.AddNode(node);
  for (const MapArc& arc : taught.map.arcs()) {
    if (arc.from != 5 && arc.from != 6) map.AddArc(arc);
  }
  EXPECT_EQ(RouteArcs(map).size(), 14u);
  const auto true_arc = WithoutArcs(ArcAt, 5, 7);
  const auto reported = [](double s) { return s < 60 ? std::min(ArcAt(s), 4) : std::max(ArcAt(s), 7); };
  const RepeatDrive drive(kFigureEight, Every(1.0, 0.5, 159.5), OneMetreRight, reported);
  const TopologicalEvaluation e = EvaluateTopological(map, taught.truth, drive.truth, drive.records);
  EXPECT_EQ(e.correct, e.frames);
  for (size_t i = 0; i < drive.s.size(); ++i) {
    const double s = drive.s[i];
    const double fraction = s / kKeySpacing - std::floor(s / kKeySpacing);
    if (fraction > 0.2 && fraction < 0.8) {
      EXPECT_EQ(e.per_frame[i].true_arc_index, true_arc(s)) << "s = " << s;
    }
  }
}

// The block driven twice, taught without the arc from key-image 5 to 6 (s = 50 .. 60) and closed from the last
// key-image onto key-image 1: the stretch is on the cycle, and steps count around it.
TEST(EvaluateTopological, CircularRouteInTwoPieces) {
  TaughtRoute taught(kBlock, 130, /*loop_to=*/1);
  Map map;
  for (const MapNode& node : taught.map.nodes()) map.AddNode(node);
  for (const MapArc& arc : taught.map.arcs()) {
    if (arc.from != 5) map.AddArc(arc);
  }
  std::vector<arc_t> expected_route;
  for (int k = 0; k <= taught.num_arcs; ++k) {
    if (k != 5) expected_route.push_back(kFirstArcId + k);
  }
  EXPECT_EQ(RouteArcs(map), expected_route);
  const auto driven = CircularArcs(130, taught.num_arcs);
  const auto true_arc = WithoutArcs(driven, 5, 6);
  const auto reported = [&](double s) { return driven(s) == 5 ? 4 : driven(s); };
  RepeatDrive drive(kBlock, Every(1.0, 0.5, 239.5), OneMetreRight, reported);
  const TopologicalEvaluation e = EvaluateTopological(map, taught.truth, drive.truth, drive.records);
  EXPECT_EQ(e.correct, e.frames);
  for (size_t i = 0; i < drive.s.size(); ++i) {
    const double s = drive.s[i];
    const double fraction = s / kKeySpacing - std::floor(s / kKeySpacing);
    if (fraction > 0.2 && fraction < 0.8) {
      EXPECT_EQ(e.per_frame[i].true_arc_index, true_arc(s)) << "s = " << s;
    }
  }
  // Steps around the cycle (arcs 1 .. 4, the stretch, arcs 6 .. 12, the loop arc: 13 steps): in the stretch on the
  // second lap (s = 175), arc 12 is 6 steps away (back over arcs 4 .. 1 and the loop arc; 7 forward), arc 1 four, and
  // arc 6 is beside the stretch.
  RepeatDrive probes(kBlock, {165.5, 175.5, 175.5, 175.5}, OneMetreRight, reported);
  probes.records[1].arc = kFirstArcId + 12;
  probes.records[2].arc = kFirstArcId + 1;
  probes.records[3].arc = kFirstArcId + 6;
  const TopologicalEvaluation p = EvaluateTopological(map, taught.truth, probes.truth, probes.records);
  EXPECT_EQ(p.per_frame[1].true_arc_index, -1);
  EXPECT_EQ(p.per_frame[1].error, 6);
  EXPECT_EQ(p.per_frame[2].error, 4);
  EXPECT_TRUE(p.per_frame[3].correct);
  EXPECT_EQ(p.per_frame[3].error, 1);
}

TEST(TruthAgainstTaughtPath, SignsFollowTheDirectionOfTravel) {
  // Taught camera centres along +z (world: x right, y down, z forward), then turning to +x.
  std::vector<TimedPose> taught(4);
  taught[1].world_from_cam.translation = Vector3d(0, 0, 5);
  taught[2].world_from_cam.translation = Vector3d(0, 0, 10);
  taught[3].world_from_cam.translation = Vector3d(5, 0, 10);
  // 0.8 m to the right (+x) of the first stretch, 1.5 m higher (height does not count), looking 0.1 rad to the
  // right of +z (a rotation about the down axis y by +0.1 turns z towards +x).
  const Matrix3d look_right = Eigen::AngleAxisd(0.1, Vector3d::UnitY()).toRotationMatrix();
  PathTruth truth = TruthAgainstTaughtPath(Rigid3d(look_right, Vector3d(0.8, -1.5, 2.5)), taught, 0, 3);
  ASSERT_TRUE(truth.valid);
  EXPECT_NEAR(truth.lateral_m, 0.8, 1e-12);
  EXPECT_NEAR(truth.distance_m, 0.8, 1e-12);
  EXPECT_NEAR(truth.heading_error_rad, 0.1, 1e-12);
  EXPECT_NEAR(truth.along_index, 0.5, 1e-12);
  // Beside the last stretch (travel along +x), 0.5 m towards -z is to the right; looking along +z is 90 degrees
  // to the left of the path.
  truth = TruthAgainstTaughtPath(Rigid3d(Matrix3d::Identity(), Vector3d(2, 0, 9.5)), taught, 0, 3);
  EXPECT_NEAR(truth.lateral_m, 0.5, 1e-12);
  EXPECT_NEAR(truth.heading_error_rad, -M_PI / 2, 1e-12);
  EXPECT_NEAR(truth.along_index, 2.4, 1e-12);
  // Restricted to the first stretch, the same camera is measured against it (a route crossing itself).
  truth = TruthAgainstTaughtPath(Rigid3d(Matrix3d::Identity(), Vector3d(2, 0, 9.5)), taught, 0, 1);
  EXPECT_NEAR(truth.distance_m, std::hypot(2.0, 4.5), 1e-12);
  EXPECT_LT(truth.along_index, 1.0 + 1e-12);
  // Fewer than two taught poses in the range: no answer.
  EXPECT_FALSE(TruthAgainstTaughtPath(Rigid3d(), taught, 2, 2).valid);
}

}  // namespace
}  // namespace retrace
