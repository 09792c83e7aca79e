#include "retrace/repeat/evaluation.h"

#include <cmath>

#include <gtest/gtest.h>

namespace retrace {
namespace {

// A straight route along x: key-images at frames 0, 10, 20, 30 (x = frame), arcs 0, 1, 2.
struct StraightRoute {
  Map map;
  std::vector<TimedPose> truth;
  StraightRoute() {
    for (int i = 0; i <= 40; ++i) {
      TimedPose pose;
      pose.timestamp = i;
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

TEST(EvaluateTopological, CountsCorrectToleratedWrongAndLost) {
  const StraightRoute route;
  const std::vector<RepeatRecord> records = {
      {15, true, 11},            // correct
      {15, true, 10},            // wrong by one (mid-arc)
      {5, true, 12},             // wrong by two
      {11, true, 10},            // near node 1: arc 0 tolerated
      {13, true, 10},            // not near a node any more: wrong
      {29, true, 12},            // near node 3: the next arc tolerated
      {25, false, kInvalidArcId},  // lost
      {38, true, 12},            // beyond the last key-image: last arc
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

TEST(EvaluateTopological, MissingPoseIsAnError) {
  const StraightRoute route;
  EXPECT_THROW(EvaluateTopological(route.map, route.truth, route.truth, {{100, true, 10}}), std::invalid_argument);
}

}  // namespace
}  // namespace retrace
