#include "retrace/nav/graph_planner.h"

#include <limits>
#include <random>
#include <stdexcept>

#include <gtest/gtest.h>

namespace retrace {
namespace {

// A map of `num_nodes` key-images (timestamps 1 s apart) and the given arcs.
struct ArcSpec {
  node_t from, to;
  std::optional<double> similarity;
  std::string kind = "tracking";
};

Map HandMadeMap(int num_nodes, const std::vector<ArcSpec>& arcs) {
  Map map;
  for (int i = 0; i < num_nodes; ++i) {
    MapNode node;
    node.id = i;
    node.source_frame = 10 * i;
    node.timestamp = 1.0 * i;
    map.AddNode(node);
  }
  for (const ArcSpec& spec : arcs) {
    MapArc arc;
    arc.from = spec.from;
    arc.to = spec.to;
    arc.similarity = spec.similarity;
    arc.kind = spec.kind;
    map.AddArc(arc);
  }
  return map;
}

//   0 --0.5-- 1 --0.5-- 2 --0.25-- 4        d = 1 / S: 0-1-2-4 costs 2 + 2 + 4 = 8,
//    \                 /                    0-3-2-4 costs 10 + 1 + 4 = 15,
//     0.1 -- 3 -- 1.0                       0-4 directly 1 / 0.05 = 20.
//   0 -------- 0.05 -------------------- 4
Map Diamond() {
  return HandMadeMap(5, {{0, 1, 0.5}, {1, 2, 0.5}, {0, 3, 0.1}, {3, 2, 1.0}, {2, 4, 0.25}, {0, 4, 0.05}});
}

TEST(GraphPlannerTest, DistancesToGoalAreTheShortestAppearanceDistances) {
  const PlanningGraph graph = BuildPlanningGraph(Diamond(), PlanOptions());
  const auto distance = DistancesToGoal(graph, 4);
  ASSERT_EQ(distance.size(), 5u);
  EXPECT_DOUBLE_EQ(distance.at(4), 0.0);
  EXPECT_DOUBLE_EQ(distance.at(2), 4.0);
  EXPECT_DOUBLE_EQ(distance.at(3), 5.0);
  EXPECT_DOUBLE_EQ(distance.at(1), 6.0);
  EXPECT_DOUBLE_EQ(distance.at(0), 8.0);
}

TEST(GraphPlannerTest, PathPrefersSimilarImagesOverAWeakShortcut) {
  const PlanningGraph graph = BuildPlanningGraph(Diamond(), PlanOptions());
  const PlannedPath path = PlanPath(graph, 0, 4);
  ASSERT_TRUE(path.found);
  EXPECT_EQ(path.nodes, (std::vector<node_t>{0, 1, 2, 4}));
  EXPECT_EQ(path.arcs, (std::vector<arc_t>{0, 1, 4}));
  EXPECT_DOUBLE_EQ(path.cost, 8.0);
  // Undirected by default (the paper's graph): the way back is the same path reversed.
  const PlannedPath back = PlanPath(graph, 4, 0);
  ASSERT_TRUE(back.found);
  EXPECT_EQ(back.nodes, (std::vector<node_t>{4, 2, 1, 0}));
  EXPECT_DOUBLE_EQ(back.cost, 8.0);
  // From the goal to itself.
  const PlannedPath stay = PlanPath(graph, 4, 4);
  ASSERT_TRUE(stay.found);
  EXPECT_EQ(stay.nodes, (std::vector<node_t>{4}));
  EXPECT_DOUBLE_EQ(stay.cost, 0.0);
}

TEST(GraphPlannerTest, DirectedGraphDrivesArcsForwardAndLinksBothWays) {
  PlanOptions options;
  options.directed = true;
  // Two routes 0 -> 1 -> 2 and 3 -> 4 -> 5, joined from 4 to 1 (the same place).
  Map map = HandMadeMap(6, {{0, 1, 0.4}, {1, 2, 0.4}, {3, 4, 0.4}, {4, 5, 0.4}, {4, 1, 0.2, "join"}});
  const PlanningGraph graph = BuildPlanningGraph(map, options);
  // Forward along route 0 to route 1 over the join (against the join arc's direction).
  PlannedPath path = PlanPath(graph, 0, 5);
  ASSERT_TRUE(path.found);
  EXPECT_EQ(path.nodes, (std::vector<node_t>{0, 1, 4, 5}));
  EXPECT_DOUBLE_EQ(path.cost, 2.5 + 5.0 + 2.5);
  // Never backwards along a route.
  EXPECT_FALSE(PlanPath(graph, 2, 0).found);
  EXPECT_FALSE(PlanPath(graph, 5, 3).found);
  // Undirected: it may.
  EXPECT_TRUE(PlanPath(BuildPlanningGraph(map, PlanOptions()), 2, 0).found);
}

TEST(GraphPlannerTest, UnreachableGoalsAndUnknownNodesGiveNoPath) {
  // Nodes 3 and 4 are an island; an arc of similarity 0 is no edge.
  const Map map = HandMadeMap(5, {{0, 1, 0.5}, {1, 2, 0.0}, {3, 4, 0.5}});
  const PlanningGraph graph = BuildPlanningGraph(map, PlanOptions());
  EXPECT_FALSE(PlanPath(graph, 0, 4).found);
  EXPECT_FALSE(PlanPath(graph, 0, 2).found);
  EXPECT_TRUE(PlanPath(graph, 0, 1).found);
  EXPECT_FALSE(PlanPath(graph, 0, 99).found);
  EXPECT_FALSE(PlanPath(graph, 99, 0).found);
  EXPECT_EQ(DistancesToGoal(graph, 4).size(), 2u);
}

TEST(GraphPlannerTest, AppearanceCostNeedsEverySimilarity) {
  const Map map = HandMadeMap(3, {{0, 1, 0.5}, {1, 2, std::nullopt}});
  try {
    BuildPlanningGraph(map, PlanOptions());
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("arc 1 has no similarity"), std::string::npos) << e.what();
  }
  // The drive cost does not need it.
  PlanOptions drive;
  drive.cost = PlanOptions::Cost::kDrive;
  const PlannedPath path = PlanPath(BuildPlanningGraph(map, drive), 0, 2);
  ASSERT_TRUE(path.found);
  EXPECT_DOUBLE_EQ(path.cost, 2.0);  // 1 s per arc
}

TEST(GraphPlannerTest, DriveCostCountsSecondsAndLinksAsOnePlace) {
  // Route 0: 0 -> 1 -> 2 -> 3 (1 s apart); a loop arc 3 -> 0 (the same place) and a zero-length cycle through it.
  PlanOptions drive;
  drive.cost = PlanOptions::Cost::kDrive;
  drive.directed = true;
  const Map map = HandMadeMap(4, {{0, 1, 0.9}, {1, 2, 0.9}, {2, 3, 0.9}, {3, 0, 0.01, "loop"}});
  const PlanningGraph graph = BuildPlanningGraph(map, drive);
  const PlannedPath path = PlanPath(graph, 1, 3);
  ASSERT_TRUE(path.found);
  EXPECT_EQ(path.nodes, (std::vector<node_t>{1, 2, 3}));
  EXPECT_DOUBLE_EQ(path.cost, 2.0);
  // Undirected, the drive back to 0 (1 s) and over the loop arc (0 s) is shorter.
  drive.directed = false;
  const PlannedPath back = PlanPath(BuildPlanningGraph(map, drive), 1, 3);
  EXPECT_EQ(back.nodes, (std::vector<node_t>{1, 0, 3}));
  EXPECT_DOUBLE_EQ(back.cost, 1.0);
  const PlannedPath over_loop = PlanPath(graph, 0, 3);
  ASSERT_TRUE(over_loop.found);
  EXPECT_EQ(over_loop.nodes, (std::vector<node_t>{0, 3}));
  EXPECT_DOUBLE_EQ(over_loop.cost, 0.0);
  // The appearance cost of the same map avoids the weak loop arc (1 / 0.01 = 100).
  const PlannedPath appearance = PlanPath(BuildPlanningGraph(map, PlanOptions()), 0, 3);
  ASSERT_TRUE(appearance.found);
  EXPECT_EQ(appearance.nodes, (std::vector<node_t>{0, 1, 2, 3}));
}

// Random graphs against Floyd-Warshall: every distance and the cost of every planned path.
TEST(GraphPlannerTest, MatchesFloydWarshallOnRandomGraphs) {
  std::mt19937 random(7);
  for (int trial = 0; trial < 50; ++trial) {
    const int n = 2 + static_cast<int>(random() % 12);
    std::vector<ArcSpec> arcs;
    std::uniform_real_distribution<double> similarity(0.01, 1.0);
    const int num_arcs = static_cast<int>(random() % (2 * n + 1));
    for (int k = 0; k < num_arcs; ++k) {
      const node_t a = random() % n, b = random() % n;
      if (a != b) arcs.push_back({a, b, similarity(random)});
    }
    const Map map = HandMadeMap(n, arcs);
    const PlanningGraph graph = BuildPlanningGraph(map, PlanOptions());
    const double inf = std::numeric_limits<double>::infinity();
    std::vector<std::vector<double>> d(n, std::vector<double>(n, inf));
    for (int i = 0; i < n; ++i) d[i][i] = 0.0;
    for (const ArcSpec& a : arcs) {
      d[a.from][a.to] = std::min(d[a.from][a.to], 1.0 / *a.similarity);
      d[a.to][a.from] = std::min(d[a.to][a.from], 1.0 / *a.similarity);
    }
    for (int k = 0; k < n; ++k)
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) d[i][j] = std::min(d[i][j], d[i][k] + d[k][j]);
    for (int goal = 0; goal < n; ++goal) {
      const auto distance = DistancesToGoal(graph, goal);
      const ShortestPathTree tree = ShortestPathsToGoal(graph, goal);
      for (int i = 0; i < n; ++i) {
        const PlannedPath path = PlanPath(graph, i, goal);
        // The tree grown once gives the same path without searching again (the Navigator's way).
        const PlannedPath from_tree = PathFromTree(tree, i, goal);
        EXPECT_EQ(from_tree.found, path.found);
        EXPECT_EQ(from_tree.nodes, path.nodes);
        if (d[i][goal] == inf) {
          EXPECT_EQ(distance.count(i), 0u);
          EXPECT_FALSE(path.found);
          continue;
        }
        ASSERT_EQ(distance.count(i), 1u);
        EXPECT_NEAR(distance.at(i), d[i][goal], 1e-9);
        ASSERT_TRUE(path.found);
        EXPECT_NEAR(path.cost, d[i][goal], 1e-9);
        EXPECT_EQ(path.nodes.front(), i);
        EXPECT_EQ(path.nodes.back(), goal);
        // Every step is an arc of the map between the two nodes, and the costs add up.
        double sum = 0.0;
        for (size_t s = 0; s < path.arcs.size(); ++s) {
          const MapArc* arc = map.FindArc(path.arcs[s]);
          ASSERT_NE(arc, nullptr);
          const bool joins = (arc->from == path.nodes[s] && arc->to == path.nodes[s + 1]) ||
                             (arc->to == path.nodes[s] && arc->from == path.nodes[s + 1]);
          EXPECT_TRUE(joins);
          sum += 1.0 / *arc->similarity;
        }
        EXPECT_NEAR(sum, path.cost, 1e-9);
      }
    }
  }
}

}  // namespace
}  // namespace retrace
