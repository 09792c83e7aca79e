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
  std::set<node_t> visited = {start};
  node_t node = start;
  while (true) {
    const MapArc* next = nullptr;
    for (const MapArc* arc : map.ArcsFrom(node)) {
      if (arc->kind != "loop" && !used.count(arc->id)) {
        next = arc;
        break;
      }
    }
    if (next == nullptr) break;
    used.insert(next->id);
    route.push_back(next->id);
    node = next->to;
    visited.insert(node);
  }
  // A circular route: the loop-closing arc from the last node back to a node already on the route, once.
  for (const MapArc* arc : map.ArcsFrom(node)) {
    if (arc->kind == "loop" && arc->to != node && visited.count(arc->to)) {
      route.push_back(arc->id);
      break;
    }
  }
  return route;
}

std::string TopologicalEvaluation::Summary() const {
  return fmt::format("{} frames: {:.1f}% correct, {} wrong ({} by >= 2 arcs), {} lost ({:.1f}%)", frames,
                     100.0 * FractionCorrect(), wrong, wrong_by_two, lost, 100.0 * FractionLost());
}

namespace {

// Projection parameter of p on the segment from `a` to `b` (0 at a, 1 at b), not clamped; 0 for a point segment.
double RawProjection(const Vector3d& a, const Vector3d& b, const Vector3d& p) {
  const Vector3d d = b - a;
  return d.squaredNorm() > 0 ? (p - a).dot(d) / d.squaredNorm() : 0.0;
}

// One record against one route arc: where its true position projects and whether the camera looks the arc's way.
struct Placement {
  double u = 0.0;         // clamped projection parameter
  double distance = 0.0;  // to the clamped projection
  double along = 0.0;     // arc length along the route from the arc's start to the clamped projection
  bool heading_ok = true;
};

}  // namespace

TopologicalEvaluation EvaluateTopological(const Map& map, const std::vector<TimedPose>& key_truth,
                                          const std::vector<TimedPose>& repeat_truth,
                                          const std::vector<RepeatRecord>& records,
                                          const TopologicalTruthOptions& options) {
  if (!options.Check()) throw std::invalid_argument("EvaluateTopological: invalid options");
  const std::vector<arc_t> route = RouteArcs(map);
  if (route.empty()) throw std::invalid_argument("EvaluateTopological: the map has no route");
  const auto pose_in = [](const std::vector<TimedPose>& truth, int64_t index) -> const Rigid3d& {
    if (index < 0 || static_cast<size_t>(index) >= truth.size()) {
      throw std::invalid_argument("EvaluateTopological: no ground-truth pose for frame " + std::to_string(index));
    }
    return truth[index].world_from_cam;
  };
  const auto key_position = [&](node_t id) { return pose_in(key_truth, map.FindNode(id)->source_frame).translation; };

  // Route arc k runs from key-image position from[k] to to[k], over `extent[k]` of arc length along the route.
  const int n = static_cast<int>(route.size());
  std::vector<Vector3d> from(n), to(n);
  std::vector<double> length(n), extent(n);
  for (int k = 0; k < n; ++k) {
    const MapArc* arc = map.FindArc(route[k]);
    from[k] = key_position(arc->from);
    to[k] = key_position(arc->to);
    length[k] = extent[k] = (to[k] - from[k]).norm();
  }
  // A circular route: the last arc closes the loop from the last key-image L onto the key-image c where arc
  // `cycle_first` starts, and the drive goes on with that arc. L and c are about the same place, c a little ahead or
  // behind: the loop arc's extent is the signed gap from L to c along the direction of travel into L. When c is behind
  // L, the laps after the first enter arc c where L is (from `cycle_entry` of its length on): a frame that has not
  // passed L is still on the arc into L.
  int cycle_first = -1;
  double cycle_entry = 0.0;
  if (n >= 2 && map.FindArc(route.back())->kind == "loop") {
    const MapArc* loop = map.FindArc(route.back());
    for (int k = 0; k + 1 < n && cycle_first < 0; ++k) {
      if (map.FindArc(route[k])->from == loop->to) cycle_first = k;
    }
    if (cycle_first >= 0) {
      const Vector3d into = length[n - 2] > 0
                                ? Vector3d(to[n - 2] - from[n - 2])
                                : pose_in(key_truth, map.FindNode(loop->from)->source_frame).rotation.col(2);
      extent[n - 1] = (to[n - 1] - from[n - 1]).dot(into.normalized());
      if (extent[n - 1] < 0 && length[cycle_first] > 0) {
        cycle_entry = std::min(1.0, -extent[n - 1] / length[cycle_first]);
      }
    }
  }
  const auto successor = [&](int k) { return k + 1 < n ? k + 1 : cycle_first; };
  // Arcs between two route arcs along the drive, in either direction: around the cycle of a circular route.
  const auto arcs_apart = [&](int a, int b) {
    if (a > b) std::swap(a, b);
    if (cycle_first < 0 || b < cycle_first) return b - a;
    const int cycle = n - cycle_first;
    const int lead_in = std::max(0, cycle_first - a);
    const int around = b - std::max(a, cycle_first);
    return lead_in + std::min(around, cycle - around);
  };

  // True positions and optical axes of the records, and how far the camera travelled in all.
  const size_t num_records = records.size();
  std::vector<Vector3d> position(num_records), axis(num_records);
  double travelled = 0.0;
  for (size_t t = 0; t < num_records; ++t) {
    const Rigid3d& pose = pose_in(repeat_truth, static_cast<int64_t>(records[t].source_index));
    position[t] = pose.translation;
    axis[t] = pose.rotation.col(2);
    if (t > 0) travelled += (position[t] - position[t - 1]).norm();
  }

  // The route unrolled in driving order: segment j is route arc arc_of[j], starts at arc length start[j] and is
  // entered at entry[j] of its length (0 but where a lap enters the cycle behind the loop-closing key-image). A
  // circular route gets as many more laps (c .. n-1, loop) as the drive can advance, and one more.
  std::vector<int> arc_of;
  std::vector<double> start, entry;
  double along_route = 0.0;
  const auto append = [&](int k, double entered) {
    arc_of.push_back(k);
    start.push_back(along_route);
    entry.push_back(entered);
    along_route += extent[k];
  };
  for (int k = 0; k < n; ++k) append(k, 0.0);
  if (cycle_first >= 0) {
    double cycle = 0.0;
    for (int k = cycle_first; k < n; ++k) cycle += extent[k];
    const double reach = (1.0 + options.speed_tolerance) * travelled + num_records * options.order_slack;
    const double laps = cycle > 0 ? std::min(std::ceil(reach / cycle) + 1.0, num_records + 1.0) : 1.0;
    for (int lap = 0; lap < static_cast<int>(laps); ++lap) {
      for (int k = cycle_first; k < n; ++k) append(k, k == cycle_first ? cycle_entry : 0.0);
    }
  }
  const int num_segments = static_cast<int>(arc_of.size());

  // Each record against each route arc as driven from `entered` of its length on (the laps share the geometry): the
  // projection clamped to that part, its distance, its arc length along the route from the arc's start, and whether
  // the camera looks the arc's way.
  const double min_cos = std::cos(options.max_heading_difference_deg * M_PI / 180.0);
  const auto place = [&](size_t t, int k, double entered) {
    Placement pl;
    pl.u = std::clamp(RawProjection(from[k], to[k], position[t]), entered, 1.0);
    pl.distance = (from[k] + pl.u * (to[k] - from[k]) - position[t]).norm();
    pl.along = pl.u * extent[k];
    pl.heading_ok = length[k] <= 0 || axis[t].dot(to[k] - from[k]) > min_cos * length[k];
    return pl;
  };
  // placements[j] for the first n segments; the laps' segments share them, but for the cycle's entry.
  const auto place_all = [&](size_t t) {
    std::vector<Placement> placements(n + 1);
    for (int k = 0; k < n; ++k) placements[k] = place(t, k, 0.0);
    if (cycle_first >= 0) placements[n] = place(t, cycle_first, cycle_entry);
    return placements;
  };
  const auto placement_of = [&](const std::vector<Placement>& placements, int j) -> const Placement& {
    return j >= n && entry[j] > 0 ? placements[n] : placements[arc_of[j]];
  };
  const auto emission = [&](const Placement& pl) {
    return pl.distance + (pl.heading_ok ? 0.0 : options.violation_cost);
  };

  // Viterbi over (record, segment). cost[j]: the cheapest labelling of the records so far that ends on segment j;
  // the first record may be anywhere on the first pass of the route.
  constexpr double kInfinity = std::numeric_limits<double>::infinity();
  std::vector<std::vector<int>> previous(num_records, std::vector<int>(num_segments, -1));
  std::vector<double> cost(num_segments, kInfinity), next_cost(num_segments);
  std::vector<Placement> placements;
  if (num_records > 0) {
    placements = place_all(0);
    for (int j = 0; j < n; ++j) cost[j] = emission(placement_of(placements, j));
  }
  for (size_t t = 1; t < num_records; ++t) {
    const std::vector<Placement> last = std::move(placements);
    placements = place_all(t);
    // Order rule: forward by (1 + tolerance) times the distance travelled, backward by as much times the distance
    // travelled against the optical axis, each plus the slack and the distances of both positions from the route.
    const Vector3d step = position[t] - position[t - 1];
    Vector3d looking = axis[t] + axis[t - 1];
    looking = looking.norm() > 1e-9 ? Vector3d(looking.normalized()) : axis[t];
    const double forward = (1.0 + options.speed_tolerance) * step.norm() + options.order_slack;
    const double backward = (1.0 + options.speed_tolerance) * std::max(0.0, -step.dot(looking)) + options.order_slack;
    const int cheapest = static_cast<int>(std::min_element(cost.begin(), cost.end()) - cost.begin());
    for (int b = 0; b < num_segments; ++b) {
      const Placement& pb = placement_of(placements, b);
      double best = cost[cheapest] + options.violation_cost;
      int best_a = cheapest;
      for (int a = 0; a < num_segments; ++a) {
        if (!(cost[a] < best)) continue;
        const Placement& pa = placement_of(last, a);
        const double advance = (start[b] + pb.along) - (start[a] + pa.along);
        const double beside = pa.distance + pb.distance;
        if (advance <= forward + beside && -advance <= backward + beside) {
          best = cost[a];
          best_a = a;
        }
      }
      next_cost[b] = best + emission(pb);
      previous[t][b] = best_a;
    }
    cost.swap(next_cost);
  }
  std::vector<int> labels(num_records);
  if (num_records > 0) {
    labels.back() = static_cast<int>(std::min_element(cost.begin(), cost.end()) - cost.begin());
    for (size_t t = num_records - 1; t > 0; --t) labels[t - 1] = previous[t][labels[t]];
  }

  TopologicalEvaluation evaluation;
  for (size_t t = 0; t < num_records; ++t) {
    const RepeatRecord& record = records[t];
    const Vector3d& p = position[t];
    const int j = labels[t];
    const int k = arc_of[j];
    FrameTruth frame;
    frame.true_arc_index = k;
    // Near a node the arc across it along the drive is tolerated: the one driven before, or the one after (on the
    // part of the arc driven, when a lap enters it behind the loop-closing key-image).
    const double u = entry[j] < 1 ? (RawProjection(from[k], to[k], p) - entry[j]) / (1.0 - entry[j]) : 0.0;
    if (u < options.near_node_fraction && j > 0) frame.tolerated_arc_index = arc_of[j - 1];
    if (u > 1.0 - options.near_node_fraction && successor(k) >= 0) frame.tolerated_arc_index = successor(k);
    if (record.localized) {
      const auto it = std::find(route.begin(), route.end(), record.arc);
      if (it != route.end()) {
        frame.estimated_arc_index = static_cast<int>(it - route.begin());
        if (length[frame.estimated_arc_index] > 0) {
          frame.true_position_on_arc = RawProjection(from[frame.estimated_arc_index], to[frame.estimated_arc_index], p);
        }
      }
    }
    ++evaluation.frames;
    if (!record.localized) {
      frame.lost = true;
      ++evaluation.lost;
    } else {
      frame.correct = frame.estimated_arc_index == frame.true_arc_index ||
                      (frame.tolerated_arc_index >= 0 && frame.estimated_arc_index == frame.tolerated_arc_index);
      frame.error = frame.estimated_arc_index < 0 ? n : arcs_apart(frame.estimated_arc_index, k);
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
