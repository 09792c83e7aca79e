#include "retrace/nav/subgoal.h"

#include <algorithm>

namespace retrace {

SubgoalUpdate AdvanceSubgoal(const PlanningGraph& graph, const std::unordered_map<node_t, double>& distance_to_goal,
                             node_t subgoal, node_t goal, const std::function<bool(node_t)>& matches) {
  SubgoalUpdate update;
  update.subgoal = subgoal;
  while (update.subgoal != goal) {
    const auto here = distance_to_goal.find(update.subgoal);
    const auto edges = graph.edges.find(update.subgoal);
    if (here == distance_to_goal.end() || edges == graph.edges.end()) break;
    // Neighbours nearer the goal (Booij 2007 §B.4), nearest first; each compared once.
    std::vector<std::pair<double, node_t>> nearer;
    for (const PlanningEdge& e : edges->second) {
      const auto d = distance_to_goal.find(e.to);
      if (d != distance_to_goal.end() && d->second < here->second) nearer.emplace_back(d->second, e.to);
    }
    std::sort(nearer.begin(), nearer.end());
    nearer.erase(std::unique(nearer.begin(), nearer.end()), nearer.end());
    bool moved = false;
    for (const auto& [d, node] : nearer) {
      if (std::find(update.compared.begin(), update.compared.end(), node) != update.compared.end()) continue;
      update.compared.push_back(node);
      if (matches(node)) {
        update.previous = update.subgoal;
        update.subgoal = node;
        ++update.advanced;
        moved = true;
        break;
      }
    }
    if (!moved) break;
  }
  update.at_goal = update.subgoal == goal;
  return update;
}

}  // namespace retrace
