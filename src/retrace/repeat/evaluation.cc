#include "retrace/repeat/evaluation.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <set>
#include <stdexcept>

#include <fmt/format.h>

namespace retrace {

std::vector<arc_t> RouteArcs(const Map& map) {
  std::vector<arc_t> route;
  if (map.arcs().empty()) return route;
  node_t start = map.arcs().front().from;
  for (const MapNode& node : map.nodes()) {
    bool has_incoming = false;
    for (const MapArc* arc : map.ArcsTo(node.id)) has_incoming |= arc->kind != "loop";
    if (!has_incoming && !map.ArcsFrom(node.id).empty()) {
      start = node.id;
      break;
    }
  }
  std::set<arc_t> used;
  node_t node = start;
  while (true) {
    const std::vector<const MapArc*> out = map.ArcsFrom(node);
    const MapArc* next = nullptr;
    for (const MapArc* arc : out) {
      if (!used.count(arc->id)) {
        next = arc;
        break;
      }
    }
    if (next == nullptr || (next->kind == "loop" && !route.empty())) break;
    used.insert(next->id);
    route.push_back(next->id);
    node = next->to;
  }
  return route;
}

std::string TopologicalEvaluation::Summary() const {
  return fmt::format("{} frames: {:.1f}% correct, {} wrong ({} by >= 2 arcs), {} lost ({:.1f}%)", frames,
                     100.0 * FractionCorrect(), wrong, wrong_by_two, lost, 100.0 * FractionLost());
}

TopologicalEvaluation EvaluateTopological(const Map& map, const std::vector<TimedPose>& key_truth,
                                          const std::vector<TimedPose>& repeat_truth,
                                          const std::vector<RepeatRecord>& records,
                                          const TopologicalTruthOptions& options) {
  const std::vector<arc_t> route = RouteArcs(map);
  if (route.empty()) throw std::invalid_argument("EvaluateTopological: the map has no route");
  const auto position_in = [](const std::vector<TimedPose>& truth, int64_t index) -> Vector3d {
    if (index < 0 || static_cast<size_t>(index) >= truth.size()) {
      throw std::invalid_argument("EvaluateTopological: no ground-truth pose for frame " + std::to_string(index));
    }
    return truth[index].world_from_cam.translation;
  };
  // Key-image positions along the route: node k and k+1 bound route arc k.
  std::vector<Vector3d> nodes;
  nodes.push_back(position_in(key_truth, map.FindNode(map.FindArc(route.front())->from)->source_frame));
  for (const arc_t id : route) nodes.push_back(position_in(key_truth, map.FindNode(map.FindArc(id)->to)->source_frame));

  TopologicalEvaluation evaluation;
  for (const RepeatRecord& record : records) {
    const Vector3d p = position_in(repeat_truth, static_cast<int64_t>(record.source_index));
    // The segment nearest to p (clamped projection).
    int best = 0;
    double best_distance = std::numeric_limits<double>::infinity();
    double best_u = 0.0;
    for (size_t k = 0; k + 1 < nodes.size(); ++k) {
      const Vector3d d = nodes[k + 1] - nodes[k];
      const double u_raw = d.squaredNorm() > 0 ? (p - nodes[k]).dot(d) / d.squaredNorm() : 0.0;
      const double u = std::clamp(u_raw, 0.0, 1.0);
      const double distance = (nodes[k] + u * d - p).norm();
      if (distance < best_distance) {
        best_distance = distance;
        best = static_cast<int>(k);
        best_u = u_raw;
      }
    }
    FrameTruth frame;
    frame.true_arc_index = best;
    if (best_u < options.near_node_fraction && best > 0) frame.tolerated_arc_index = best - 1;
    if (best_u > 1.0 - options.near_node_fraction && best + 1 < static_cast<int>(route.size())) {
      frame.tolerated_arc_index = best + 1;
    }
    if (record.localized) {
      const auto it = std::find(route.begin(), route.end(), record.arc);
      if (it != route.end()) {
        frame.estimated_arc_index = static_cast<int>(it - route.begin());
        const Vector3d d = nodes[frame.estimated_arc_index + 1] - nodes[frame.estimated_arc_index];
        if (d.squaredNorm() > 0)
          frame.true_position_on_arc = (p - nodes[frame.estimated_arc_index]).dot(d) / d.squaredNorm();
      }
    }
    ++evaluation.frames;
    if (!record.localized) {
      frame.lost = true;
      ++evaluation.lost;
    } else {
      frame.correct = frame.estimated_arc_index == frame.true_arc_index ||
                      (frame.tolerated_arc_index >= 0 && frame.estimated_arc_index == frame.tolerated_arc_index);
      frame.error = frame.estimated_arc_index < 0 ? static_cast<int>(route.size())
                                                  : std::abs(frame.estimated_arc_index - frame.true_arc_index);
      if (frame.correct) {
        ++evaluation.correct;
      } else {
        ++evaluation.wrong;
        if (frame.error >= 2) ++evaluation.wrong_by_two;
      }
    }
    evaluation.per_frame.push_back(frame);
  }
  return evaluation;
}

}  // namespace retrace
