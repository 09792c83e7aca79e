#include "retrace/repeat/belief.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <string>
#include <unordered_set>

#include "retrace/util/statistics.h"

namespace retrace {
namespace {

constexpr double kInvSqrt2Pi = 0.3989422804014327;

// Frames the teach drive spent on an arc (its key-images' source frames), at least 1.
double TeachFrames(const Map& map, const MapArc& arc) {
  const MapNode* from = map.FindNode(arc.from);
  const MapNode* to = map.FindNode(arc.to);
  if (from == nullptr || to == nullptr || from->source_frame < 0 || to->source_frame < 0) return 1.0;
  return std::max<double>(1.0, std::abs(static_cast<double>(to->source_frame - from->source_frame)));
}

}  // namespace

bool PlaceBeliefOptions::Check(std::string* error) const {
  const auto fail = [&](const std::string& message) {
    if (error != nullptr) *error = message;
    return false;
  };
  if (bins_per_arc < 2) return fail("bins_per_arc must be >= 2");
  if (!(relative_speed_noise >= 0) || !(position_noise > 0)) return fail("motion noise must be positive");
  if (!(unknown_speed_max > unknown_speed_min)) return fail("unknown_speed_max must exceed unknown_speed_min");
  if (teach_frame_step < 1) return fail("teach_frame_step must be >= 1");
  if (speed_steps < 1 || speed_memory_frames < 1) return fail("speed_steps and speed_memory_frames must be >= 1");
  if (!(jump_probability > 0) || !(jump_probability < 1)) return fail("jump_probability must be in (0, 1)");
  if (!(static_fraction >= 0) || !(static_fraction < 1)) return fail("static_fraction must be in [0, 1)");
  if (!(outlier_range > 0)) return fail("outlier_range must be positive");
  if (reach < 1) return fail("reach must be >= 1");
  if (!(node_tolerance >= 0) || !(node_tolerance < 0.5)) return fail("node_tolerance must be in [0, 0.5)");
  if (!(min_confidence > 0) || !(min_confidence <= 1)) return fail("min_confidence must be in (0, 1]");
  if (!(min_inlier_probability > 0) || !(min_inlier_probability < 1)) {
    return fail("min_inlier_probability must be in (0, 1)");
  }
  if (!(planned_branch_probability > 0) || !(planned_branch_probability < 1)) {
    return fail("planned_branch_probability must be in (0, 1)");
  }
  return true;
}

PlaceBelief::PlaceBelief(const Map& map, const PlaceBeliefOptions& options) : options_(options) {
  std::string error;
  if (!options_.Check(&error)) throw std::invalid_argument("PlaceBeliefOptions: " + error);
  for (const MapArc& arc : map.arcs()) {
    index_[arc.id] = static_cast<int>(arcs_.size());
    ArcNode node;
    node.id = arc.id;
    arcs_.push_back(node);
  }
  // The graph: an arc continues into every arc leaving its end node except the one straight back.
  for (const MapArc& arc : map.arcs()) {
    ArcNode& node = arcs_[index_.at(arc.id)];
    for (const MapArc* next : map.ArcsFrom(arc.to)) {
      if (next->to == arc.from) continue;  // straight back
      node.successors.push_back(index_.at(next->id));
      node.successor_ids.push_back(next->id);
    }
    for (const MapArc* previous : map.ArcsTo(arc.from)) {
      if (previous->from == arc.to) continue;
      node.predecessors.push_back(index_.at(previous->id));
      node.predecessor_ids.push_back(previous->id);
    }
  }
  // Gaps in a map teach left in pieces: the last arc of a piece that ends inside the drive continues, after the
  // stretch the teach drive made no arc for, into the first arc of the piece it made next (Map::DrivenArcAcrossGap).
  for (size_t k = 0; k < arcs_.size(); ++k) {
    if (!arcs_[k].successors.empty()) continue;
    const arc_t next = map.DrivenArcAcrossGap(map.FindArc(arcs_[k].id)->to, +1);
    const int n = Index(next);
    if (n < 0 || n == static_cast<int>(k) || !arcs_[n].predecessors.empty() || arcs_[n].across_gap_before >= 0) {
      continue;
    }
    arcs_[k].across_gap_after = n;
    arcs_[n].across_gap_before = static_cast<int>(k);
    arcs_[k].successor_ids.push_back(arcs_[n].id);
    arcs_[n].predecessor_ids.push_back(arcs_[k].id);
  }
  // Lengths in one common unit: breadth first from each component's first arc, through the scales stored at the
  // nodes (ℓ_out = s ℓ_in, design §1), else (and across a gap) through the teach frames spent on each arc.
  std::vector<bool> known(arcs_.size(), false);
  for (size_t seed = 0; seed < arcs_.size(); ++seed) {
    if (known[seed]) continue;
    known[seed] = true;
    arcs_[seed].length = 1.0;
    std::deque<int> queue{static_cast<int>(seed)};
    while (!queue.empty()) {
      const int k = queue.front();
      queue.pop_front();
      const MapArc& arc = *map.FindArc(arcs_[k].id);
      const auto visit = [&](int other, bool forward) {
        if (known[other]) return;
        const MapArc& next = *map.FindArc(arcs_[other].id);
        const std::optional<double> scale =
            forward ? map.ScaleAt(arc.to, arc.id, next.id) : map.ScaleAt(arc.from, next.id, arc.id);
        double ratio = TeachFrames(map, next) / TeachFrames(map, arc);
        if (scale && *scale > 0 && std::isfinite(*scale)) ratio = forward ? *scale : 1.0 / *scale;
        arcs_[other].length = arcs_[k].length * ratio;
        known[other] = true;
        queue.push_back(other);
      };
      for (const int s : arcs_[k].successors) visit(s, true);
      for (const int p : arcs_[k].predecessors) visit(p, false);
      if (arcs_[k].across_gap_after >= 0) visit(arcs_[k].across_gap_after, true);
      if (arcs_[k].across_gap_before >= 0) visit(arcs_[k].across_gap_before, false);
    }
  }
  // A teach frame spans teach_frame_step frames of the sequence the key-images are numbered in.
  for (ArcNode& arc : arcs_) {
    arc.teach_frame_length =
        arc.length * options_.teach_frame_step / TeachFrames(map, *map.FindArc(arc.id));
  }
  // Virtual arcs beyond the route's ends (ArcNode::virtual_of). Beyond the teach drive's first and last key-images
  // they are as long as the median arc (a route's last arc is often short: teach registers its last frame); where a
  // piece of a disconnected map ends inside the drive, the virtual arc is the gap: as long as the teach drive took
  // to the next piece (its frames there at the last arc's length per frame), continued by the next piece's first
  // arc (which has no virtual arc before it); without a next piece, as long as the arc itself.
  const size_t real_arcs = arcs_.size();
  std::vector<double> lengths;
  for (const ArcNode& arc : arcs_) lengths.push_back(arc.length);
  const double typical_length = lengths.empty() ? 1.0 : Median(lengths);
  int64_t first_frame = std::numeric_limits<int64_t>::max(), last_frame = std::numeric_limits<int64_t>::min();
  for (const MapNode& node : map.nodes()) {
    first_frame = std::min(first_frame, node.source_frame);
    last_frame = std::max(last_frame, node.source_frame);
  }
  for (size_t k = 0; k < real_arcs; ++k) {
    for (const bool beyond_end : {true, false}) {
      if (!(beyond_end ? arcs_[k].successors : arcs_[k].predecessors).empty()) continue;
      if (!beyond_end && arcs_[k].across_gap_before >= 0) continue;  // the gap before it is there
      ArcNode extension;
      extension.id = arcs_[k].id;
      extension.teach_frame_length = arcs_[k].teach_frame_length;
      const MapArc& arc = *map.FindArc(arcs_[k].id);
      const MapNode* end = map.FindNode(beyond_end ? arc.to : arc.from);
      const bool drive_end = end != nullptr && end->source_frame == (beyond_end ? last_frame : first_frame);
      extension.length = drive_end ? std::max(arcs_[k].length, typical_length) : arcs_[k].length;
      extension.virtual_of = static_cast<int>(k);
      const int index = static_cast<int>(arcs_.size());
      const int next = arcs_[k].across_gap_after;
      if (beyond_end && next >= 0 && end != nullptr) {
        const MapNode* start = map.FindNode(map.FindArc(arcs_[next].id)->from);
        const double gap_frames =
            start == nullptr ? 1.0 : std::max(1.0, static_cast<double>(start->source_frame - end->source_frame));
        extension.length = arcs_[k].length * gap_frames / TeachFrames(map, arc);
        extension.successors.push_back(next);
        arcs_[next].predecessors.push_back(index);
      }
      (beyond_end ? extension.predecessors : extension.successors).push_back(static_cast<int>(k));
      (beyond_end ? arcs_[k].successors : arcs_[k].predecessors).push_back(index);
      arcs_[k].virtual_children.push_back(index);
      arcs_.push_back(extension);
    }
  }
  SetPlannedArcs({});
  mass_.assign(arcs_.size() * options_.bins_per_arc, 0.0);
  scratch_.assign(mass_.size(), 0.0);
  diff_.assign(arcs_.size() * (options_.bins_per_arc + 1), 0.0);
  Reset();
}

void PlaceBelief::SetPlannedArcs(const std::vector<arc_t>& arcs) {
  const std::unordered_set<arc_t> planned(arcs.begin(), arcs.end());
  for (ArcNode& arc : arcs_) {
    const size_t n = arc.successors.size();
    size_t on_plan = 0;
    for (const int s : arc.successors) on_plan += arcs_[s].virtual_of < 0 && planned.count(arcs_[s].id) != 0;
    arc.successor_shares.assign(n, n == 0 ? 0.0 : 1.0 / n);
    if (on_plan == 0 || on_plan == n) continue;
    const double p = options_.planned_branch_probability;
    for (size_t i = 0; i < n; ++i) {
      const int s = arc.successors[i];
      const bool is_planned = arcs_[s].virtual_of < 0 && planned.count(arcs_[s].id) != 0;
      arc.successor_shares[i] = is_planned ? p / on_plan : (1.0 - p) / (n - on_plan);
    }
  }
}

void PlaceBelief::Reset() {
  if (!mass_.empty()) std::fill(mass_.begin(), mass_.end(), 1.0 / mass_.size());
  off_map_ = 0.0;
  last_place_.reset();
  step_origin_.reset();
  newest_step_frame_ = 0;
  steps_.clear();
  speed_.reset();
  estimate_ = PlaceEstimate();
  ComputeEstimate();
  estimate_.evidence = false;
  estimate_.tracking = false;
}

void PlaceBelief::ResetTo(arc_t arc) {
  const int k = Index(arc);
  if (k < 0) return;
  Reset();
  const int bins = options_.bins_per_arc;
  const double floor = options_.jump_probability / mass_.size();
  std::fill(mass_.begin(), mass_.end(), floor);
  for (int i = 0; i < bins; ++i) mass_[k * bins + i] += (1.0 - options_.jump_probability) / bins;
  ComputeEstimate();
  estimate_.evidence = false;
  estimate_.tracking = false;
}

int PlaceBelief::Index(arc_t arc) const {
  const auto it = index_.find(arc);
  return it == index_.end() ? -1 : it->second;
}

double PlaceBelief::ArcLength(arc_t arc) const {
  const int k = Index(arc);
  return k < 0 ? 1.0 : arcs_[k].length;
}

const std::vector<arc_t>& PlaceBelief::Successors(arc_t arc) const {
  static const std::vector<arc_t> kNone;
  const int k = Index(arc);
  return k < 0 ? kNone : arcs_[k].successor_ids;
}

const std::vector<arc_t>& PlaceBelief::Predecessors(arc_t arc) const {
  static const std::vector<arc_t> kNone;
  const int k = Index(arc);
  return k < 0 ? kNone : arcs_[k].predecessor_ids;
}

double PlaceBelief::MassAt(int k) const {
  const int bins = options_.bins_per_arc;
  double sum = 0.0;
  for (int i = 0; i < bins; ++i) sum += mass_[k * bins + i];
  for (const int v : arcs_[k].virtual_children) {
    for (int i = 0; i < bins; ++i) sum += mass_[v * bins + i];
  }
  return sum;
}

double PlaceBelief::ConfidenceAt(int k) const {
  const int bins = options_.bins_per_arc;
  double confidence = MassAt(k);
  for (const int s : arcs_[k].successors) {
    if (arcs_[s].virtual_of >= 0) continue;  // counted in MassAt
    for (int i = 0; i < bins && (i + 0.5) / bins < options_.node_tolerance; ++i) confidence += mass_[s * bins + i];
  }
  for (const int p : arcs_[k].predecessors) {
    if (arcs_[p].virtual_of >= 0) {
      // The gap before the first arc of a piece (the virtual arc past the previous piece's end, counted there too):
      // the topological truth tolerates both arcs around a stretch the map has no arc for.
      if (arcs_[p].virtual_of != k) {
        for (int i = 0; i < bins; ++i) confidence += mass_[p * bins + i];
      }
      continue;
    }
    for (int i = bins - 1; i >= 0 && (i + 0.5) / bins > 1.0 - options_.node_tolerance; --i) {
      confidence += mass_[p * bins + i];
    }
  }
  return std::min(1.0, confidence);
}

double PlaceBelief::Mass(arc_t arc) const {
  const int k = Index(arc);
  return k < 0 ? 0.0 : MassAt(k);
}

double PlaceBelief::Confidence(arc_t arc) const {
  const int k = Index(arc);
  return k < 0 ? 0.0 : ConfidenceAt(k);
}

arc_t PlaceBelief::ReportedArc(arc_t tracked) const {
  const int k = Index(tracked);
  const int e = Index(estimate_.arc);
  if (k < 0 || e < 0 || e == k || !estimate_.tracking) return tracked;
  if (arcs_[k].across_gap_after != e && arcs_[k].across_gap_before != e) return tracked;
  return estimate_.confidence > ConfidenceAt(k) ? estimate_.arc : tracked;
}

double PlaceBelief::MeasurementSupport(arc_t arc, const PlaceMeasurement& measurement) const {
  const int k = Index(arc);
  if (k < 0 || !(measurement.sigma > 0)) return 0.0;
  const std::optional<double> at =
      Distance(GraphPlace{arc, 0.0}, GraphPlace{measurement.arc, measurement.along}, options_.reach);
  if (!at) return 0.0;
  // The span Confidence counts, in common units from the arc's start.
  double before = 0.0, after = 0.0;
  for (const int p : arcs_[k].predecessors) before = std::max(before, options_.node_tolerance * arcs_[p].length);
  for (const int s : arcs_[k].successors) after = std::max(after, options_.node_tolerance * arcs_[s].length);
  const double sigma = measurement.sigma * ArcLength(measurement.arc);
  const auto normal_cdf = [](double z) { return 0.5 * std::erfc(-z / std::sqrt(2.0)); };
  return normal_cdf((arcs_[k].length + after - *at) / sigma) - normal_cdf((-before - *at) / sigma);
}

std::optional<double> PlaceBelief::SpeedOn(arc_t arc) const {
  if (!speed_) return std::nullopt;
  return *speed_ / ArcLength(arc);
}

void PlaceBelief::DepositAt(std::vector<double>* target, int index, double along, double mass) const {
  const int bins = options_.bins_per_arc;
  const int i = std::clamp(static_cast<int>(along * bins), 0, bins - 1);
  (*target)[index * bins + i] += mass;
}

void PlaceBelief::DepositUniform(std::vector<double>* target, int index, double low, double high, double mass) const {
  // `mass` spread evenly over [low, high] ⊂ [0, 1] of the arc: partial end bins directly, the full bins between
  // them through the difference array diff_ (one pass in Predict turns it into masses).
  const int bins = options_.bins_per_arc;
  const double span = (high - low) * bins;  // in bins
  const int first = std::clamp(static_cast<int>(low * bins), 0, bins - 1);
  const int last = std::clamp(static_cast<int>(high * bins), 0, bins - 1);
  if (first == last || !(span > 1e-12)) {
    (*target)[index * bins + first] += mass;
    return;
  }
  const double density = mass / span;  // per bin
  (*target)[index * bins + first] += density * (first + 1 - low * bins);
  (*target)[index * bins + last] += density * (high * bins - last);
  if (last > first + 1) {
    diff_[index * (bins + 1) + first + 1] += density;
    diff_[index * (bins + 1) + last] -= density;
  }
}

void PlaceBelief::Deposit(std::vector<double>* target, int index, double along, double low, double high, double mass,
                          int depth) const {
  // The camera at `along` moves by a distance uniform in [low, high] (common units): the part of that range that
  // stays on this arc is spread over it, the rest continues into the following (preceding) arcs, split at a
  // junction by the successors' shares (equally, or towards the planned branch) and equally among predecessors;
  // past a virtual arc (beyond a route's end or before its start) it leaves the map.
  const ArcNode& arc = arcs_[index];
  const double from = along + low / arc.length;
  const double to = along + high / arc.length;
  const double width = to - from;
  if (!(width > 1e-12)) {
    if (from >= 0.0 && from < 1.0) {
      DepositAt(target, index, from, mass);
      return;
    }
  } else {
    const double inside_from = std::max(from, 0.0);
    const double inside_to = std::min(to, 1.0);
    if (inside_to > inside_from) {
      DepositUniform(target, index, inside_from, inside_to, mass * (inside_to - inside_from) / width);
    }
  }
  const double beyond = width > 1e-12 ? std::max(0.0, to - std::max(from, 1.0)) / width : (from >= 1.0 ? 1.0 : 0.0);
  const double before = width > 1e-12 ? std::max(0.0, std::min(to, 0.0) - from) / width : (from < 0.0 ? 1.0 : 0.0);
  if (beyond > 0.0) {
    if (arc.successors.empty()) {
      off_map_pending_ += mass * beyond;  // past a virtual arc: off the map
    } else if (depth > 8) {
      DepositAt(target, index, 1.0, mass * beyond);
    } else {
      // The range past the end, measured from the end, in common units.
      const double rest_low = (std::max(from, 1.0) - 1.0) * arc.length;
      const double rest_high = (to - 1.0) * arc.length;
      for (size_t i = 0; i < arc.successors.size(); ++i) {
        Deposit(target, arc.successors[i], 0.0, rest_low, rest_high, mass * beyond * arc.successor_shares[i],
                depth + 1);
      }
    }
  }
  if (before > 0.0) {
    if (arc.predecessors.empty()) {
      off_map_pending_ += mass * before;
    } else if (depth > 8) {
      DepositAt(target, index, 0.0, mass * before);
    } else {
      const double rest_low = from * arc.length;
      const double rest_high = std::min(to, 0.0) * arc.length;
      const double share = mass * before / arc.predecessors.size();
      for (const int previous : arc.predecessors) {
        Deposit(target, previous, 1.0, rest_low, rest_high, share, depth + 1);
      }
    }
  }
}

void PlaceBelief::Predict(int frames) {
  if (mass_.empty() || frames < 1) return;
  const int bins = options_.bins_per_arc;
  std::fill(scratch_.begin(), scratch_.end(), 0.0);
  std::fill(diff_.begin(), diff_.end(), 0.0);
  off_map_pending_ = 0.0;
  const double largest = *std::max_element(mass_.begin(), mass_.end());
  // The motion distribution as contiguous boxes of uniform displacement: one box without the speed (uniform over
  // [min, max] arc lengths per frame), seven with it (a Gaussian cut at ±3.5σ into intervals of σ, each with its
  // probability). Bins far below the largest one (the uniform floor) stay where they are: moving a flat floor
  // changes nothing that matters.
  static const double kBoxProbability[7] = {0.0060, 0.0606, 0.2417, 0.3829, 0.2417, 0.0606, 0.0060};
  const double frames_d = static_cast<double>(frames);
  struct Box {
    double low, high, probability;
  };
  std::vector<Box> boxes;
  for (size_t k = 0; k < arcs_.size(); ++k) {
    const double length = arcs_[k].length;
    boxes.clear();
    if (speed_) {
      const double mean = *speed_ * frames_d;
      const double sigma = std::sqrt(frames_d * (std::pow(options_.relative_speed_noise * *speed_, 2) +
                                                 std::pow(options_.position_noise * length, 2)));
      for (int j = 0; j < 7; ++j) {
        boxes.push_back({mean + (j - 3.5) * sigma, mean + (j - 2.5) * sigma, kBoxProbability[j] / 0.9995});
      }
    } else {
      const double step = arcs_[k].teach_frame_length;
      boxes.push_back({options_.unknown_speed_min * frames_d * step, options_.unknown_speed_max * frames_d * step, 1.0});
    }
    for (int i = 0; i < bins; ++i) {
      const double m = mass_[k * bins + i];
      if (m <= options_.static_fraction * largest) {
        scratch_[k * bins + i] += m;
        continue;
      }
      // The bin's mass spread over the bin (its position is known to a bin): the box widens by one bin.
      const double along = (i + 0.5) / bins;
      const double half_bin = 0.5 * length / bins;
      for (const Box& box : boxes) {
        Deposit(&scratch_, static_cast<int>(k), along, box.low - half_bin, box.high + half_bin, m * box.probability,
                0);
      }
    }
  }
  // The difference arrays into masses.
  for (size_t k = 0; k < arcs_.size(); ++k) {
    double running = 0.0;
    for (int i = 0; i < bins; ++i) {
      running += diff_[k * (bins + 1) + i];
      scratch_[k * bins + i] += running;
    }
  }
  // Jumps: a small fraction of the mass anywhere on the map (from the map and from off it).
  off_map_ += off_map_pending_;
  double total = off_map_;
  for (const double m : scratch_) total += m;
  const double floor = options_.jump_probability / scratch_.size();
  const double keep = (1.0 - options_.jump_probability) / (total > 0 ? total : 1.0);
  for (size_t c = 0; c < mass_.size(); ++c) mass_[c] = keep * scratch_[c] + floor;
  off_map_ *= keep;
}

void PlaceBelief::ReachableOffsets(int index, int reach, std::vector<std::pair<int, double>>* offsets) const {
  // Breadth first along the graph in both directions; each arc once, at its fewest hops.
  offsets->clear();
  std::vector<std::pair<int, double>> frontier_forward{{index, 0.0}}, frontier_backward{{index, 0.0}};
  std::vector<int> seen{index};
  offsets->push_back({index, 0.0});
  for (int hop = 0; hop < reach; ++hop) {
    std::vector<std::pair<int, double>> next_forward, next_backward;
    for (const auto& [k, offset] : frontier_forward) {
      for (const int s : arcs_[k].successors) {
        if (std::find(seen.begin(), seen.end(), s) != seen.end()) continue;
        seen.push_back(s);
        next_forward.push_back({s, offset + arcs_[k].length});
      }
    }
    for (const auto& [k, offset] : frontier_backward) {
      for (const int p : arcs_[k].predecessors) {
        if (std::find(seen.begin(), seen.end(), p) != seen.end()) continue;
        seen.push_back(p);
        next_backward.push_back({p, offset - arcs_[p].length});
      }
    }
    offsets->insert(offsets->end(), next_forward.begin(), next_forward.end());
    offsets->insert(offsets->end(), next_backward.begin(), next_backward.end());
    frontier_forward.swap(next_forward);
    frontier_backward.swap(next_backward);
  }
}

std::vector<double> PlaceBelief::Update(const std::vector<PlaceMeasurement>& measurements, size_t frame) {
  std::vector<double> inlier_probabilities;
  const int bins = options_.bins_per_arc;
  std::vector<std::pair<int, double>> offsets;
  for (const PlaceMeasurement& m : measurements) {
    const int k = Index(m.arc);
    if (k < 0 || !std::isfinite(m.along) || !(m.sigma > 0) || mass_.empty()) {
      inlier_probabilities.push_back(0.0);
      continue;
    }
    const double epsilon = std::clamp(m.outlier_probability, 1e-6, 1.0 - 1e-6);
    const double outlier = epsilon / (m.outlier_range > 0 ? m.outlier_range : options_.outlier_range);
    // Every place explains the measurement as an outlier; the places on k's line within reach also as an inlier.
    ReachableOffsets(k, options_.reach, &offsets);
    const double length_k = arcs_[k].length;
    std::vector<std::pair<size_t, double>> inliers;  // cell, prior mass times the inlier likelihood
    double total_inlier = 0.0;
    for (const auto& [j, offset] : offsets) {
      const double width = arcs_[j].length / (bins * length_k);  // a bin in k's arc lengths
      const double variance = m.sigma * m.sigma + width * width / 12.0;
      const double norm = (1.0 - epsilon) * kInvSqrt2Pi / std::sqrt(variance);
      for (int i = 0; i < bins; ++i) {
        double x = (offset + (i + 0.5) / bins * arcs_[j].length) / length_k;
        const double d2 = (x - m.along) * (x - m.along) / variance;
        if (d2 > 60.0) continue;
        const size_t cell = static_cast<size_t>(j) * bins + i;
        const double inlier = mass_[cell] * norm * std::exp(-0.5 * d2);
        inliers.push_back({cell, inlier});
        total_inlier += inlier;
      }
    }
    // The mass on and off the map sums to 1, so the outlier part of the evidence is `outlier` itself.
    const double total = outlier + total_inlier;
    inlier_probabilities.push_back(total_inlier / total);
    const double scale = outlier / total;
    for (double& c : mass_) c *= scale;
    off_map_ *= scale;  // off the map, a placement can only be wrong
    for (const auto& [cell, inlier] : inliers) mass_[cell] += inlier / total;
  }
  ComputeEstimate();
  estimate_.evidence = false;
  for (const double p : inlier_probabilities) estimate_.evidence |= p >= options_.min_inlier_probability;
  estimate_.tracking = estimate_.evidence && estimate_.confidence >= options_.min_confidence;

  // The speed from the steps of the estimated position between frames with evidence. A second update in the same
  // frame (the localizer's, when the tracks were given up and the camera relocalized within the frame) replaces that
  // frame's estimate, and so its step: the step is taken again from the frame before.
  if (estimate_.evidence && estimate_.arc != kInvalidArcId) {
    const GraphPlace place{estimate_.arc, estimate_.along};
    if (last_place_ && frame == last_place_frame_) {
      if (newest_step_frame_ == frame && !steps_.empty()) steps_.erase(steps_.begin());
      last_place_ = step_origin_;
      last_place_frame_ = step_origin_frame_;
    }
    std::optional<double> step;
    if (last_place_ && frame > last_place_frame_ &&
        frame - last_place_frame_ <= static_cast<size_t>(options_.speed_memory_frames)) {
      const std::optional<double> distance = Distance(*last_place_, place, options_.reach);
      if (distance) step = *distance / static_cast<double>(frame - last_place_frame_);
    }
    step_origin_ = last_place_;
    step_origin_frame_ = last_place_frame_;
    newest_step_frame_ = step ? frame : 0;
    if (step) {
      steps_.insert(steps_.begin(), *step);
      if (static_cast<int>(steps_.size()) > options_.speed_steps) steps_.pop_back();
    } else {
      steps_.clear();
    }
    speed_ = steps_.size() >= 2 ? std::optional<double>(Median(steps_)) : std::nullopt;
    last_place_ = place;
    last_place_frame_ = frame;
  } else if (last_place_ && frame > last_place_frame_ + options_.speed_memory_frames) {
    steps_.clear();
    speed_.reset();
    last_place_.reset();
  }
  return inlier_probabilities;
}

void PlaceBelief::ComputeEstimate() {
  const int bins = options_.bins_per_arc;
  const size_t n = arcs_.size();
  if (n == 0) return;
  // The reported arc: the largest confidence (ties: the larger mass on the arc itself).
  int best = -1;
  double best_confidence = -1.0, best_mass = -1.0;
  for (size_t k = 0; k < n; ++k) {
    if (arcs_[k].virtual_of >= 0) continue;
    const double confidence = ConfidenceAt(static_cast<int>(k));
    const double mass = MassAt(static_cast<int>(k));
    if (confidence > best_confidence + 1e-12 ||
        (std::abs(confidence - best_confidence) <= 1e-12 && best >= 0 && mass > best_mass)) {
      best = static_cast<int>(k);
      best_confidence = confidence;
      best_mass = mass;
    }
  }
  if (best < 0) return;
  // Posterior mean and spread of the position on arc k: its own bins, its virtual extensions and the tolerated bins
  // of its neighbours, in its arc lengths.
  const auto mean_on = [&](int k, double* along, double* sigma) {
    double sum = 0.0, sum_x = 0.0, sum_xx = 0.0;
    const auto add = [&](int j, int i, double offset) {
      const double m = mass_[j * bins + i];
      const double x = (offset + (i + 0.5) / bins * arcs_[j].length) / arcs_[k].length;
      sum += m;
      sum_x += m * x;
      sum_xx += m * x * x;
    };
    for (int i = 0; i < bins; ++i) add(k, i, 0.0);
    for (const int s : arcs_[k].successors) {
      const bool extension = arcs_[s].virtual_of >= 0;
      for (int i = 0; i < bins && (extension || (i + 0.5) / bins < options_.node_tolerance); ++i) {
        add(s, i, arcs_[k].length);
      }
    }
    for (const int p : arcs_[k].predecessors) {
      const bool extension = arcs_[p].virtual_of >= 0;
      for (int i = bins - 1; i >= 0 && (extension || (i + 0.5) / bins > 1.0 - options_.node_tolerance); --i) {
        add(p, i, -arcs_[p].length);
      }
    }
    *along = sum > 0 ? sum_x / sum : 0.5;
    *sigma = sum > 0 ? std::sqrt(std::max(0.0, sum_xx / sum - *along * *along)) : 1.0;
  };
  double along = 0.5, sigma = 1.0;
  mean_on(best, &along, &sigma);
  // Near a node both arcs meeting there are correct within the tolerance, and their confidences are nearly equal;
  // the larger then picks the arc the camera is leaving even when the mass has crossed the node (the report one
  // arc behind a camera that is in fact past the tolerance). When the posterior mean lies beyond the arc's end
  // (before its start), the arc on that side holding the most mass is reported instead, if it is trusted as well
  // (confidence at least min_confidence); in every other case the largest confidence decides.
  if (along > 1.0 || along < 0.0) {
    const std::vector<int>& side = along > 1.0 ? arcs_[best].successors : arcs_[best].predecessors;
    int across = -1;
    for (const int j : side) {
      if (arcs_[j].virtual_of >= 0) continue;
      if (across < 0 || MassAt(j) > MassAt(across)) across = j;
    }
    const double across_confidence = across >= 0 ? ConfidenceAt(across) : 0.0;
    if (across >= 0 && across_confidence >= options_.min_confidence) {
      best = across;
      best_confidence = across_confidence;
      mean_on(best, &along, &sigma);
    }
  }
  estimate_.arc = arcs_[best].id;
  estimate_.confidence = best_confidence;
  estimate_.along = along;
  estimate_.sigma = sigma;
}

std::optional<double> PlaceBelief::Distance(const GraphPlace& from, const GraphPlace& to, int max_arcs) const {
  const int a = Index(from.arc);
  const int b = Index(to.arc);
  if (a < 0 || b < 0) return std::nullopt;
  if (a == b) return (to.along - from.along) * arcs_[a].length;
  std::vector<std::pair<int, double>> offsets;
  ReachableOffsets(a, max_arcs, &offsets);
  for (const auto& [j, offset] : offsets) {
    if (j == b) return offset + to.along * arcs_[b].length - from.along * arcs_[a].length;
  }
  return std::nullopt;
}

}  // namespace retrace
