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
  // The pieces start at the nodes with an outgoing (non-loop) arc and no incoming one, in teach order.
  std::vector<const MapNode*> starts;
  for (const MapNode& node : map.nodes()) {
    bool has_incoming = false, has_outgoing = false;
    for (const MapArc* arc : map.ArcsTo(node.id)) has_incoming |= arc->kind != "loop";
    for (const MapArc* arc : map.ArcsFrom(node.id)) has_outgoing |= arc->kind != "loop";
    if (!has_incoming && has_outgoing) starts.push_back(&node);
  }
  std::stable_sort(starts.begin(), starts.end(),
                   [](const MapNode* a, const MapNode* b) { return a->source_frame < b->source_frame; });
  if (starts.empty()) starts.push_back(map.FindNode(map.arcs().front().from));
  std::set<arc_t> used;
  std::set<node_t> visited;
  for (const MapNode* start : starts) {
    // A piece: from its start, each node's first unused outgoing arc that is not a loop-closing one.
    node_t node = start->id;
    visited.insert(node);
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
  }
  if (route.empty()) return route;
  // A circular route: the loop-closing arc from the last node of the route (or else from a key-image the teach drive
  // made after it, reached over a stretch without arcs) back to a node on the route, once.
  const node_t last = map.FindArc(route.back())->to;
  const int64_t last_frame = map.FindNode(last)->source_frame;
  const MapArc* loop = nullptr;
  for (const MapArc& arc : map.arcs()) {
    if (arc.kind != "loop" || arc.to == arc.from || !visited.count(arc.to)) continue;
    if (arc.from == last) {
      loop = &arc;
      break;
    }
    if (loop == nullptr && !visited.count(arc.from) && map.FindNode(arc.from)->source_frame > last_frame) loop = &arc;
  }
  if (loop != nullptr) route.push_back(loop->id);
  return route;
}

std::string TopologicalEvaluation::Summary() const {
  return fmt::format("{} frames: {:.1f}% correct, {} wrong ({} by >= 2 arcs), {} lost ({:.1f}%)", frames,
                     100.0 * FractionCorrect(), wrong, wrong_by_two, lost, 100.0 * FractionLost());
}

namespace {

// Whether the route arc at index `estimated` is the frame's true arc or one tolerated near a node or a stretch.
bool IsTrueOrTolerated(const FrameTruth& truth, int estimated) {
  return estimated >= 0 && (estimated == truth.true_arc_index || estimated == truth.tolerated_arc_index ||
                            estimated == truth.tolerated_after_arc_index);
}

// Projection parameter of p on the segment from `a` to `b` (0 at a, 1 at b), not clamped; 0 for a point segment.
double RawProjection(const Vector3d& a, const Vector3d& b, const Vector3d& p) {
  const Vector3d d = b - a;
  return d.squaredNorm() > 0 ? (p - a).dot(d) / d.squaredNorm() : 0.0;
}

// A straight part of the route from one key-image to the next in driving order: a route arc, or a part of a stretch
// between two pieces of a disconnected route (no arc).
struct Element {
  Vector3d from, to;    // true key-image positions
  double length = 0.0;  // |to - from|
  double extent = 0.0;  // arc length along the route (the loop-closing arc: a signed gap)
  int arc = -1;         // index into RouteArcs; -1 in a stretch between pieces
  int step = 0;         // place along the route, counting arcs and stretches between pieces one each
};

// One record against one element: where its true position projects and whether the camera looks the element's way.
struct Placement {
  double u = 0.0;         // clamped projection parameter
  double distance = 0.0;  // to the clamped projection
  double along = 0.0;     // arc length along the route from the element's start to the clamped projection
  bool heading_ok = true;
};

// Whether `p` is abeam the node between `before` and `after` (consecutive arcs along the drive) within `fraction` of
// the shorter one's length: its offset from the node along the route's direction there (the mean of the two arcs'
// unit directions), and on the node's half of both arcs (in a hairpin that direction crosses both arcs).
bool AbeamOfNode(const Element& before, const Element& after, const Vector3d& p, double fraction) {
  if (before.length <= 0 || after.length <= 0) return false;
  const Vector3d direction = (before.to - before.from) / before.length + (after.to - after.from) / after.length;
  if (direction.norm() < 1e-6) return false;
  return std::abs((p - after.from).dot(direction.normalized())) < fraction * std::min(before.length, after.length) &&
         RawProjection(before.from, before.to, p) > 0.5 && RawProjection(after.from, after.to, p) < 0.5;
}

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

  // The route's elements in driving order: its arcs, and between two pieces the polyline through the key-images the
  // teach drive made from the end of the one to the start of the other (in source_frame order).
  const int n = static_cast<int>(route.size());
  std::vector<Element> elements;
  std::vector<int> element_of_arc(n);
  int steps = 0;
  const auto add = [&](const Vector3d& a, const Vector3d& b, int arc, int step) {
    Element element;
    element.from = a;
    element.to = b;
    element.length = element.extent = (b - a).norm();
    element.arc = arc;
    element.step = step;
    elements.push_back(element);
  };
  for (int k = 0; k < n; ++k) {
    const MapArc* arc = map.FindArc(route[k]);
    const node_t end = k > 0 ? map.FindArc(route[k - 1])->to : arc->from;
    if (end != arc->from) {
      const int64_t left = map.FindNode(end)->source_frame, reached = map.FindNode(arc->from)->source_frame;
      std::vector<const MapNode*> passed;
      for (const MapNode& node : map.nodes()) {
        if (node.source_frame > left && node.source_frame < reached) passed.push_back(&node);
      }
      std::stable_sort(passed.begin(), passed.end(),
                       [](const MapNode* a, const MapNode* b) { return a->source_frame < b->source_frame; });
      Vector3d a = key_position(end);
      for (const MapNode* node : passed) {
        const Vector3d b = pose_in(key_truth, node->source_frame).translation;
        add(a, b, -1, steps);
        a = b;
      }
      add(a, key_position(arc->from), -1, steps++);
    }
    element_of_arc[k] = static_cast<int>(elements.size());
    add(key_position(arc->from), key_position(arc->to), k, steps++);
  }
  const int m = static_cast<int>(elements.size());
  // The arcs on either side of each stretch between pieces (of an arc: itself).
  std::vector<int> arc_before(m), arc_after(m);
  for (int e = 0; e < m; ++e) {
    arc_before[e] = elements[e].arc >= 0 || e == 0 ? elements[e].arc : arc_before[e - 1];
  }
  for (int e = m - 1; e >= 0; --e) {
    arc_after[e] = elements[e].arc >= 0 || e == m - 1 ? elements[e].arc : arc_after[e + 1];
  }

  // A circular route: the last arc closes the loop from the last key-image L onto the key-image c where the arc in
  // element `cycle_first` starts, and the drive goes on with that arc. L and c are about the same place, c a little
  // ahead or behind: the loop arc's extent is the signed gap from L to c along the direction of travel into L. When c
  // is behind L, the laps after the first enter arc c where L is (from `cycle_entry` of its length on): a frame that
  // has not passed L is still on the arc into L.
  int cycle_first = -1;
  double cycle_entry = 0.0;
  if (n >= 2 && map.FindArc(route.back())->kind == "loop") {
    const MapArc* loop = map.FindArc(route.back());
    for (int k = 0; k + 1 < n && cycle_first < 0; ++k) {
      if (map.FindArc(route[k])->from == loop->to) cycle_first = element_of_arc[k];
    }
    if (cycle_first >= 0) {
      Element& closing = elements.back();
      const Element& into = elements[m - 2];
      const Vector3d direction = into.length > 0
                                     ? Vector3d(into.to - into.from)
                                     : pose_in(key_truth, map.FindNode(loop->from)->source_frame).rotation.col(2);
      closing.extent = (closing.to - closing.from).dot(direction.normalized());
      if (closing.extent < 0 && elements[cycle_first].length > 0) {
        cycle_entry = std::min(1.0, -closing.extent / elements[cycle_first].length);
      }
    }
  }
  const auto successor = [&](int e) { return e + 1 < m ? e + 1 : cycle_first; };
  // Steps between two places along the drive, in either direction: around the cycle of a circular route.
  const auto steps_apart = [&](int a, int b) {
    if (a > b) std::swap(a, b);
    const int first = cycle_first >= 0 ? elements[cycle_first].step : steps;
    if (b < first) return b - a;
    const int cycle = steps - first;
    const int lead_in = std::max(0, first - a);
    const int around = b - std::max(a, first);
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

  // The route unrolled in driving order: segment j is element element_of[j], starts at arc length start[j] and is
  // entered at entry[j] of its length (0 but where a lap enters the cycle behind the loop-closing key-image). A
  // circular route gets as many more laps (c .. loop) as the drive can advance, and one more.
  std::vector<int> element_of;
  std::vector<double> start, entry;
  double along_route = 0.0;
  const auto append = [&](int e, double entered) {
    element_of.push_back(e);
    start.push_back(along_route);
    entry.push_back(entered);
    along_route += elements[e].extent;
  };
  for (int e = 0; e < m; ++e) append(e, 0.0);
  if (cycle_first >= 0) {
    double cycle = 0.0;
    for (int e = cycle_first; e < m; ++e) cycle += elements[e].extent;
    const double reach = (1.0 + options.speed_tolerance) * travelled + num_records * options.order_slack;
    const double laps = cycle > 0 ? std::min(std::ceil(reach / cycle) + 1.0, num_records + 1.0) : 1.0;
    for (int lap = 0; lap < static_cast<int>(laps); ++lap) {
      for (int e = cycle_first; e < m; ++e) append(e, e == cycle_first ? cycle_entry : 0.0);
    }
  }
  const int num_segments = static_cast<int>(element_of.size());

  // Each record against each element as driven from `entered` of its length on (the laps share the geometry): the
  // projection clamped to that part, its distance, its arc length along the route from the element's start, and
  // whether the camera looks the element's way.
  const double min_cos = std::cos(options.max_heading_difference_deg * M_PI / 180.0);
  const auto place = [&](size_t t, int e, double entered) {
    const Element& el = elements[e];
    Placement pl;
    pl.u = std::clamp(RawProjection(el.from, el.to, position[t]), entered, 1.0);
    pl.distance = (el.from + pl.u * (el.to - el.from) - position[t]).norm();
    pl.along = pl.u * el.extent;
    pl.heading_ok = el.length <= 0 || axis[t].dot(el.to - el.from) > min_cos * el.length;
    return pl;
  };
  // placements[e] for the m elements; the laps' segments share them, but for the cycle's entry.
  const auto place_all = [&](size_t t) {
    std::vector<Placement> placements(m + 1);
    for (int e = 0; e < m; ++e) placements[e] = place(t, e, 0.0);
    if (cycle_first >= 0) placements[m] = place(t, cycle_first, cycle_entry);
    return placements;
  };
  const auto placement_of = [&](const std::vector<Placement>& placements, int j) -> const Placement& {
    return j >= m && entry[j] > 0 ? placements[m] : placements[element_of[j]];
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
    for (int j = 0; j < m; ++j) cost[j] = emission(placement_of(placements, j));
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
  const double near = options.near_node_fraction;
  for (size_t t = 0; t < num_records; ++t) {
    const RepeatRecord& record = records[t];
    const Vector3d& p = position[t];
    const int j = labels[t];
    const int e = element_of[j];
    const Element& el = elements[e];
    FrameTruth frame;
    frame.true_arc_index = el.arc;
    if (el.arc < 0) {
      // Between two pieces: no true arc; the arcs the map offers on either side of the stretch are tolerated.
      frame.tolerated_arc_index = arc_before[e];
      frame.tolerated_after_arc_index = arc_after[e];
    } else {
      // Near a node the arc across it along the drive is tolerated, the one driven before or the one after (not
      // across a stretch between pieces): near by the raw projection on this arc (on the part of it driven, when a
      // lap enters it behind the loop-closing key-image), or abeam the node.
      const int before = j > 0 ? element_of[j - 1] : -1;
      const int after = successor(e);
      const double u = entry[j] < 1 ? (RawProjection(el.from, el.to, p) - entry[j]) / (1.0 - entry[j]) : 0.0;
      if (before >= 0 && elements[before].arc >= 0 &&
          (u < near || (entry[j] == 0 && AbeamOfNode(elements[before], el, p, near)))) {
        frame.tolerated_arc_index = elements[before].arc;
      }
      if (after >= 0 && elements[after].arc >= 0 && (u > 1.0 - near || AbeamOfNode(el, elements[after], p, near))) {
        frame.tolerated_arc_index = elements[after].arc;
      }
    }
    if (record.localized) {
      const auto it = std::find(route.begin(), route.end(), record.arc);
      if (it != route.end()) {
        frame.estimated_arc_index = static_cast<int>(it - route.begin());
        const Element& estimated = elements[element_of_arc[frame.estimated_arc_index]];
        if (estimated.length > 0) frame.true_position_on_arc = RawProjection(estimated.from, estimated.to, p);
      }
    }
    ++evaluation.frames;
    if (!record.localized) {
      frame.lost = true;
      ++evaluation.lost;
    } else {
      const int estimated = frame.estimated_arc_index;
      frame.correct = IsTrueOrTolerated(frame, estimated);
      frame.error = estimated < 0 ? steps : steps_apart(elements[element_of_arc[estimated]].step, el.step);
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

bool IsCorrectEstimate(const FrameTruth& truth, const std::vector<arc_t>& route, arc_t arc) {
  const auto it = std::find(route.begin(), route.end(), arc);
  return it != route.end() && IsTrueOrTolerated(truth, static_cast<int>(it - route.begin()));
}

PathTruth TruthAgainstTaughtPath(const Rigid3d& world_from_cam, const std::vector<TimedPose>& taught, size_t first,
                                 size_t last) {
  PathTruth truth;
  last = std::min(last, taught.size() - 1);
  if (taught.size() < 2 || first >= last) return truth;
  const auto flat = [](const Vector3d& x) { return Vector2d(x.x(), x.z()); };
  const Vector2d c = flat(world_from_cam.translation);
  double best = std::numeric_limits<double>::infinity();
  Vector2d tangent = Vector2d::UnitY();
  for (size_t i = first; i < last; ++i) {
    const Vector2d a = flat(taught[i].world_from_cam.translation);
    const Vector2d ab = flat(taught[i + 1].world_from_cam.translation) - a;
    if (!(ab.squaredNorm() > 0)) continue;
    const double t = std::clamp((c - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    const Vector2d offset = c - (a + t * ab);
    if (offset.norm() < best) {
      best = offset.norm();
      tangent = ab.normalized();
      truth.along_index = static_cast<double>(i) + t;
      truth.lateral_m = offset.dot(Vector2d(tangent.y(), -tangent.x()));
    }
  }
  if (!std::isfinite(best)) return truth;
  truth.distance_m = best;
  const Vector2d look = flat(world_from_cam.rotation * Vector3d::UnitZ());
  truth.heading_error_rad = std::atan2(tangent.y() * look.x() - tangent.x() * look.y(), tangent.dot(look));
  truth.valid = look.norm() > 1e-9;
  return truth;
}

}  // namespace retrace
