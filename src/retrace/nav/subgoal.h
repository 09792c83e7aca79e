#pragma once

// Dynamic subgoals (Booij 2007 §B.4): the robot drives towards one key-image at a time. "The robot tries to pick a
// new subgoal by comparing the newest observation with all the neighbors of node c that have a smaller distance D_c
// to the goal node. If one of these images matches, it becomes the new current subgoal c. This procedure is repeated
// for the neighbors of the new c, until the node is found that is closest to the goal node and still robustly
// matches the new observation." Navigation ends when the subgoal is the goal.
//
//     D: distances to the goal (graph_planner.h DistancesToGoal)
//     c ── n1 (D < D_c, matches) ── n2 (D < D_n1, matches) ── n3 (D < D_n2, does not match)   =>   c ← n2
//      └── m  (D > D_c): never tried (it leads away from the goal)
//
// Neighbours of c nearer the goal are tried from the nearest on, and the first that matches is taken: the matching
// neighbour closest to the goal, with as few image comparisons as that needs.

#include <functional>
#include <unordered_map>
#include <vector>

#include "retrace/nav/graph_planner.h"

namespace retrace {

struct SubgoalUpdate {
  node_t subgoal = kInvalidNodeId;  // the new subgoal (the old one when no neighbour nearer the goal matched)
  int advanced = 0;                 // steps taken along the graph
  node_t previous = kInvalidNodeId; // the subgoal before the last step (invalid when none was taken)
  bool at_goal = false;             // the subgoal is the goal: stop
  std::vector<node_t> compared;     // nodes compared with the observation, in order
};

// Advances `subgoal` as far towards the goal as the observation allows. `distance_to_goal` holds D for every node
// that reaches the goal (nodes absent from it are never taken); `matches(n)` says whether the current observation
// robustly matches key-image n (wide-baseline matching and geometry in the Navigator; anything in tests).
SubgoalUpdate AdvanceSubgoal(const PlanningGraph& graph, const std::unordered_map<node_t, double>& distance_to_goal,
                             node_t subgoal, node_t goal, const std::function<bool(node_t)>& matches);

}  // namespace retrace
