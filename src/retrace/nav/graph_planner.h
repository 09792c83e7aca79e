#pragma once

// Planning on the appearance graph (Booij 2007 §B.4, design §7).
//
// Every arc of a map is an edge between its two key-images. Its length is the appearance distance d_ij = 1 / S_ij
// of the paper (S_ij: the similarity stored with the arc, MapArc::similarity), so that a shortest path prefers
// key-images that share many features; or, as the paper notes its appearance distance is not a metric one, the
// drive's own measure: the seconds the teach drive took between the two key-images (MapNode::timestamp; the frames
// between them when the timestamps do not differ). Arcs made by wide-baseline matching between places of different
// times of a drive or of different drives (kinds "loop" and "join") link images of one place and have a drive
// length of PlanOptions::link_seconds.
//
// Dijkstra's algorithm gives the distance D_i from every node to the goal (the paper's heuristic while driving);
// the path from a start node follows, at each node, an edge with d_ij + D_j = D_i (the shortest-path tree the
// search builds, so that edges of length 0 never make it cycle).
//
//            d = 1 / S         D_i: shortest distance from node i to the goal over such edges
//    (i) ───────────── (j)     next(i): a j with d_ij + D_j = D_i
//
// An edge of similarity 0 (or unknown similarity under the appearance cost) cannot be planned through; the graph
// builder refuses a map whose arcs have no similarity (maps written before schema 3) for the appearance cost.

#include <string>
#include <unordered_map>
#include <vector>

#include "retrace/map/map.h"

namespace retrace {

struct PlanOptions {
  enum class Cost {
    kAppearance,  // d_ij = 1 / S_ij (Booij 2007 §B.4); default
    kDrive,       // seconds of the teach drive between the key-images (frames when the timestamps are equal)
  };
  Cost cost = Cost::kAppearance;
  // Edges only in the direction their arc was driven, links (loop, join) both ways: for a camera that cannot see
  // backwards along a route (a forward-looking perspective camera). false: every arc both ways, as the paper's
  // undirected graph of panoramic images.
  bool directed = false;
  // Drive cost of a "loop" or "join" arc (two images of one place), seconds.
  double link_seconds = 0.0;

  bool Check(std::string* error = nullptr) const;
};

struct PlanningEdge {
  node_t to = kInvalidNodeId;
  arc_t arc = kInvalidArcId;
  double length = 0.0;  // > 0 (or 0 for links under the drive cost)
};

// Adjacency lists over the nodes of a map (every node present, possibly without edges).
struct PlanningGraph {
  std::unordered_map<node_t, std::vector<PlanningEdge>> edges;  // edges leaving each node

  bool HasNode(node_t node) const { return edges.count(node) != 0; }
  // Adds a node (no-op when present) and a directed edge.
  void AddEdge(node_t from, const PlanningEdge& edge);
};

// The planning graph of a map. Throws std::invalid_argument, naming the arc, when the appearance cost meets an arc
// without similarity.
PlanningGraph BuildPlanningGraph(const Map& map, const PlanOptions& options);

// Dijkstra (1959) over the reversed edges from the goal: the distance of every node that reaches the goal and the
// edge it leaves by on a shortest path (a tree rooted at the goal: following it never cycles, even over edges of
// length 0). Of equally short ways the one found first is kept; edges are relaxed from the smaller node id on.
struct ShortestPathTree {
  std::unordered_map<node_t, double> distance;    // D_i; absent for nodes that cannot reach the goal
  std::unordered_map<node_t, PlanningEdge> next;  // the edge from a node towards the goal
};
ShortestPathTree ShortestPathsToGoal(const PlanningGraph& graph, node_t goal);

// The shortest distance D_i from every node that can reach the goal (others are absent); D_goal = 0. Booij 2007
// §B.4.
std::unordered_map<node_t, double> DistancesToGoal(const PlanningGraph& graph, node_t goal);

struct PlannedPath {
  bool found = false;
  std::vector<node_t> nodes;  // from the start to the goal, both included
  std::vector<arc_t> arcs;    // the arc of each step (nodes.size() - 1)
  double cost = 0.0;          // sum of the edge lengths
};

// The shortest path from `start` to `goal` (not found when the goal cannot be reached or a node is not in the
// graph). Of equally short paths, the one the search found first (deterministic for a given graph).
PlannedPath PlanPath(const PlanningGraph& graph, node_t start, node_t goal);
// The same from a tree already grown towards `goal` (its root): no search.
PlannedPath PathFromTree(const ShortestPathTree& tree, node_t start, node_t goal);

}  // namespace retrace
