#include "retrace/nav/subgoal.h"

#include <set>

#include <gtest/gtest.h>

namespace retrace {
namespace {

// A graph of the given undirected edges, all of length 1.
PlanningGraph Graph(const std::vector<std::pair<node_t, node_t>>& edges) {
  PlanningGraph graph;
  arc_t arc = 0;
  for (const auto& [a, b] : edges) {
    graph.AddEdge(a, {b, arc, 1.0});
    graph.AddEdge(b, {a, arc, 1.0});
    ++arc;
  }
  return graph;
}

std::function<bool(node_t)> Matching(const std::set<node_t>& nodes) {
  return [nodes](node_t n) { return nodes.count(n) != 0; };
}

// A route 0 - 1 - 2 - 3 - 4 with the goal at 4.
TEST(SubgoalTest, AdvancesToTheMatchingNodeNearestTheGoal) {
  const PlanningGraph graph = Graph({{0, 1}, {1, 2}, {2, 3}, {3, 4}});
  const auto distance = DistancesToGoal(graph, 4);
  SubgoalUpdate update = AdvanceSubgoal(graph, distance, 0, 4, Matching({0, 1, 2}));
  EXPECT_EQ(update.subgoal, 2);
  EXPECT_EQ(update.advanced, 2);
  EXPECT_EQ(update.previous, 1);  // the last step was 1 -> 2
  EXPECT_FALSE(update.at_goal);
  EXPECT_EQ(update.compared, (std::vector<node_t>{1, 2, 3}));
  // Nothing nearer matches: the subgoal stays.
  update = AdvanceSubgoal(graph, distance, 2, 4, Matching({0, 1}));
  EXPECT_EQ(update.subgoal, 2);
  EXPECT_EQ(update.advanced, 0);
  EXPECT_EQ(update.previous, kInvalidNodeId);
  // Everything matches: straight to the goal, which ends navigation.
  update = AdvanceSubgoal(graph, distance, 0, 4, Matching({0, 1, 2, 3, 4}));
  EXPECT_EQ(update.subgoal, 4);
  EXPECT_TRUE(update.at_goal);
  EXPECT_TRUE(AdvanceSubgoal(graph, distance, 4, 4, Matching({})).at_goal);
}

// A junction at 2: the goal 5 lies on the branch 2 - 4 - 5, not on 2 - 3. Neighbours farther from the goal are never
// compared, even when they would match; among nearer ones the nearest that matches wins.
TEST(SubgoalTest, FollowsTheBranchTowardsTheGoalAtAJunction) {
  //   0 - 1 - 2 - 3
  //           |
  //           4 - 5
  const PlanningGraph graph = Graph({{0, 1}, {1, 2}, {2, 3}, {2, 4}, {4, 5}});
  const auto distance = DistancesToGoal(graph, 5);
  SubgoalUpdate update = AdvanceSubgoal(graph, distance, 1, 5, Matching({0, 1, 2, 3}));
  EXPECT_EQ(update.subgoal, 2);
  EXPECT_EQ(update.compared, (std::vector<node_t>{2, 4}));  // never 0 or 3: they lead away from the goal
  update = AdvanceSubgoal(graph, distance, 1, 5, Matching({2, 3, 4}));
  EXPECT_EQ(update.subgoal, 4);
  EXPECT_EQ(update.compared, (std::vector<node_t>{2, 4, 5}));
}

// Of two neighbours nearer the goal, the nearer is compared first and taken when both match.
TEST(SubgoalTest, PrefersTheNeighbourNearerTheGoal) {
  // 0 has two neighbours towards the goal 3: 1 (D = 2) and 2 (D = 1).
  PlanningGraph graph;
  graph.AddEdge(0, {1, 0, 1.0});
  graph.AddEdge(0, {2, 1, 1.5});
  graph.AddEdge(1, {3, 2, 2.0});
  graph.AddEdge(2, {3, 3, 1.0});
  const auto distance = DistancesToGoal(graph, 3);
  ASSERT_DOUBLE_EQ(distance.at(1), 2.0);
  ASSERT_DOUBLE_EQ(distance.at(2), 1.0);
  const SubgoalUpdate update = AdvanceSubgoal(graph, distance, 0, 3, Matching({1, 2}));
  EXPECT_EQ(update.subgoal, 2);
  EXPECT_EQ(update.compared.front(), 2);
}

// A subgoal that cannot reach the goal (absent from the distances) stays where it is.
TEST(SubgoalTest, UnreachableSubgoalStays) {
  const PlanningGraph graph = Graph({{0, 1}, {2, 3}});
  const auto distance = DistancesToGoal(graph, 3);
  const SubgoalUpdate update = AdvanceSubgoal(graph, distance, 0, 3, Matching({0, 1, 2, 3}));
  EXPECT_EQ(update.subgoal, 0);
  EXPECT_FALSE(update.at_goal);
  EXPECT_TRUE(update.compared.empty());
}

}  // namespace
}  // namespace retrace
