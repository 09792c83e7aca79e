#include "retrace/nav/graph_planner.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <queue>
#include <stdexcept>

#include <fmt/format.h>

namespace retrace {

bool PlanOptions::Check(std::string* error) const {
  if (!(link_seconds >= 0 && std::isfinite(link_seconds))) {
    if (error != nullptr) *error = "link_seconds must be finite and not negative";
    return false;
  }
  return true;
}

void PlanningGraph::AddEdge(node_t from, const PlanningEdge& edge) {
  edges[edge.to];  // the target is a node of the graph too
  edges[from].push_back(edge);
}

PlanningGraph BuildPlanningGraph(const Map& map, const PlanOptions& options) {
  std::string error;
  if (!options.Check(&error)) throw std::invalid_argument("PlanOptions: " + error);
  PlanningGraph graph;
  for (const MapNode& node : map.nodes()) graph.edges[node.id];
  for (const MapArc& arc : map.arcs()) {
    const bool link = arc.IsLink();
    double length = 0.0;
    if (options.cost == PlanOptions::Cost::kAppearance) {
      if (!arc.similarity) {
        throw std::invalid_argument(fmt::format(
            "arc {} has no similarity (a map written before schema 3); plan with the drive cost instead", arc.id));
      }
      if (!(*arc.similarity > 0.0)) continue;  // d = 1 / 0: no edge
      length = 1.0 / *arc.similarity;          // Booij 2007 §B.4: d_ij = 1 / S_ij
    } else if (link) {
      length = options.link_seconds;
    } else {
      const MapNode* from = map.FindNode(arc.from);
      const MapNode* to = map.FindNode(arc.to);
      if (from == nullptr || to == nullptr) continue;
      length = std::abs(to->timestamp - from->timestamp);
      if (!(length > 0.0)) length = static_cast<double>(std::abs(to->source_frame - from->source_frame));
    }
    graph.AddEdge(arc.from, {arc.to, arc.id, length});
    if (!options.directed || link) graph.AddEdge(arc.to, {arc.from, arc.id, length});
  }
  return graph;
}

ShortestPathTree ShortestPathsToGoal(const PlanningGraph& graph, node_t goal) {
  ShortestPathTree tree;
  if (!graph.HasNode(goal)) return tree;
  std::unordered_map<node_t, std::vector<std::pair<node_t, PlanningEdge>>> incoming;
  std::vector<node_t> nodes;
  for (const auto& entry : graph.edges) nodes.push_back(entry.first);
  std::sort(nodes.begin(), nodes.end());
  for (const node_t from : nodes) {
    for (const PlanningEdge& e : graph.edges.at(from)) incoming[e.to].emplace_back(from, e);
  }
  using Entry = std::pair<double, node_t>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> queue;
  tree.distance[goal] = 0.0;
  queue.emplace(0.0, goal);
  while (!queue.empty()) {
    const auto [d, node] = queue.top();
    queue.pop();
    if (d > tree.distance[node]) continue;
    const auto it = incoming.find(node);
    if (it == incoming.end()) continue;
    for (const auto& [previous, edge] : it->second) {
      const double candidate = d + edge.length;
      const auto known = tree.distance.find(previous);
      if (known == tree.distance.end() || candidate < known->second) {
        tree.distance[previous] = candidate;
        tree.next[previous] = edge;
        queue.emplace(candidate, previous);
      }
    }
  }
  return tree;
}

std::unordered_map<node_t, double> DistancesToGoal(const PlanningGraph& graph, node_t goal) {
  return ShortestPathsToGoal(graph, goal).distance;
}

PlannedPath PlanPath(const PlanningGraph& graph, node_t start, node_t goal) {
  if (!graph.HasNode(start) || !graph.HasNode(goal)) return PlannedPath();
  return PathFromTree(ShortestPathsToGoal(graph, goal), start, goal);
}

PlannedPath PathFromTree(const ShortestPathTree& tree, node_t start, node_t goal) {
  PlannedPath path;
  if (tree.distance.count(start) == 0 || tree.distance.count(goal) == 0 || tree.distance.at(goal) != 0.0) return path;
  path.nodes.push_back(start);
  for (node_t node = start; node != goal;) {
    const PlanningEdge& edge = tree.next.at(node);
    path.cost += edge.length;
    path.arcs.push_back(edge.arc);
    path.nodes.push_back(edge.to);
    node = edge.to;
  }
  path.found = true;
  return path;
}

}  // namespace retrace
