#pragma once

// Where the camera is on the map graph: one belief over places (design §6.1).
//
// The paper decides the topological place by geometric tests: eq. (9) for transitions, σ_p gates for the current
// geometries (Segvic 2009 §5.2). retrace keeps those tests as evidence and decides the place with a discrete Bayes
// filter (a histogram filter; Thrun, Burgard, Fox, "Probabilistic Robotics", 2005, §4.1) over positions on the
// graph. The state space is every arc of the map cut into `bins_per_arc` equal bins of its position `along`
// (0 at the arc's first key-image, 1 at its second). Every arc k has a length ℓ_k in one common unit: the stored
// relative scale at each node converts the unit of one arc into the next (design §1: ℓ_next = s · ℓ_k), and where
// the map stores no scale the frames the teach drive spent on each arc stand in (a car drives at a similar speed on
// neighbouring arcs).
//
// Each frame:
//  1. Predict (motion model): every bin's mass moves by the camera's displacement d along the graph, continuing into
//     the following arcs past an arc's end (into each of them, equally, at a junction — or, when a plan is set,
//     `planned_branch_probability` of it into the planned branch, see SetPlannedArcs) and into the previous ones
//     before its start. Past a route's last key-image the camera is on a virtual arc continuing the last arc (and
//     before the first on one preceding it), which counts as the route's last (first) arc; past that virtual arc it is
//     off the map (a mass of its own, which placements do not explain). Where a piece of a map teach left in pieces
//     ends inside the drive, the virtual arc is the gap the teach drive crossed (as long as it took there) and leads
//     on into the first arc of the piece the drive made next. With the speed v known (common units per frame,
//     the median of the last steps of the estimated position), d ~ N(v Δ, Δ ((α v)² + (σ₀ ℓ)²)) for Δ frames: α =
//     `relative_speed_noise` (the speed changes and is estimated from noisy positions), σ₀ = `position_noise` arc
//     lengths. With the speed unknown (after a start, a loss, or a jump) d is uniform over [`unknown_speed_min`,
//     `unknown_speed_max`] teach frames per frame (the distance the teach drive covered in one of its frames there).
//     Then a fraction `jump_probability` of the mass is spread uniformly over the whole map: the belief may be
//     wrong, or the robot carried elsewhere; this is what lets consistent evidence elsewhere win.
//  2. Update (measurement model): every placement of the camera this frame yields — the absolute pose in an arc's
//     reconstruction, the current geometries W_t:a / W_t:b brought into the arc's frame, a key-image verified by
//     wide-baseline matching — is a measurement z (arc lengths of its arc k, anywhere on k's line: z = 1.5 is half
//     way along the arc after k) with a standard deviation σ and an outlier probability ε:
//         p(z | place) = ε / R + (1 - ε) N(z; x(place), σ² + q²),
//     x(place) the place's coordinate on k's line (reachable within `reach` arcs of k; farther places explain z only
//     as an outlier), R = `outlier_range` arc lengths (the span over which a wrong placement lands; a key-image
//     retrieval chose among C candidates gives R = C), q the bin
//     width in k's units over √12 (quantisation). The posterior probability that a measurement is an inlier is
//     kept: a frame has its own evidence when one of its measurements is an inlier with probability
//     ≥ `min_inlier_probability`.
//  3. Estimate: the reported arc is the one with the largest confidence, the probability that the camera is on it
//     or within `node_tolerance` of its ends on a neighbouring arc (the topological truth tolerates ±1 arc near a
//     node, design §9, so this is the probability that the report is correct) — or, when the posterior mean has
//     crossed that arc's end (start), the arc across holding the most mass if its confidence reaches
//     `min_confidence` too (near a node both are nearly equally likely correct, and the largest confidence alone
//     favoured the arc the camera was leaving). The state is `tracking` only when the confidence is at least
//     `min_confidence` and the frame has its own evidence; otherwise the localizer reports `lost`.
//
// Measurements of one frame from the same tracked features are not independent; the localizer therefore gives the
// belief one placement per frame from its tracked features (the most accurate one) and the bootstrap's key-image
// separately.

#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "retrace/map/map.h"

namespace retrace {

// A place on the map graph: an arc and a position along it (0 at its first key-image, 1 at its second).
struct GraphPlace {
  arc_t arc = kInvalidArcId;
  double along = 0.0;
};

// The camera placed on `arc` at `along` (arc lengths of that arc; beyond [0, 1] when the camera is past an end),
// with its standard deviation `sigma` (arc lengths) and the probability that the placement is wrong.
struct PlaceMeasurement {
  arc_t arc = kInvalidArcId;
  double along = 0.0;
  double sigma = 0.1;
  double outlier_probability = 0.1;
  // Arc lengths over which this placement lands when it is wrong; 0: PlaceBeliefOptions::outlier_range. A key-image
  // picked by retrieval among C candidates lands on any of them when wrong (C arc lengths).
  double outlier_range = 0.0;
};

struct PlaceBeliefOptions {
  // Bins per arc. Placements by the absolute pose are good to a few hundredths of an arc; 32 bins keep the
  // quantisation (bin / √12 = 0.009) below that.
  int bins_per_arc = 32;

  // Motion model. Standard deviation of one frame's displacement relative to the speed: the speed is the median of
  // the last `speed_steps` steps of the estimated position, and a car brakes and accelerates.
  double relative_speed_noise = 0.3;
  // ... plus this many arc lengths per frame (a camera at rest still has a position noise).
  double position_noise = 0.05;
  // With the speed unknown, one frame moves the camera anywhere in [min, max] teach frames — the distance the teach
  // drive covered in that many of its frames on the arc (the arc's length over the teach frames it spans; maps
  // without source frames: one per arc): backward a little, forward as far as a repeat at twice the teach speed and
  // half its frame rate. In arcs that is up to 2-4 where key-images are one or two teach frames apart (kitti07 at
  // 320 px in its turns, which passes about one per frame) and well under one arc in the simulated town (3-8 teach
  // frames per arc), where a bound of three arcs per frame let a relocalization right after a kidnapped start
  // report a look-alike three arcs ahead (`retrace bench kidnap --seed 2` on the map of validation drive seed2).
  double unknown_speed_min = -1.0;
  double unknown_speed_max = 4.0;
  // Frames of the teach sequence per teach frame (`teach --every`; the key-images keep their numbers in the sequence).
  // LoadMapForLocalizer sets it from the map's metadata `frames_every`.
  int teach_frame_step = 1;
  // Steps of the estimated position whose median is the speed, ...
  int speed_steps = 3;
  // ... forgotten after this many frames without evidence (the speed is then unknown again).
  int speed_memory_frames = 5;
  // Per frame, this fraction of the mass is spread uniformly over the map (kidnapping, a wrong belief).
  double jump_probability = 1e-3;
  // At a junction of a planned route (SetPlannedArcs), the probability that the camera continues into the planned
  // branch: the robot is steered along the plan, and takes another branch only when that steering fails (a missed
  // turn, an overshoot). A prior, not a gate: the placements of two or three frames on the other branch outweigh it
  // (an absolute pose's likelihood ratio between two branches is many orders of magnitude), which is how the
  // localizer notices a branch the plan did not choose. Without a plan, or at a junction where the plan takes all
  // or none of the branches, the mass is split equally.
  double planned_branch_probability = 0.9;
  // Bins holding less than this fraction of the largest bin's mass are not moved by the motion model (the uniform
  // floor the jumps leave; moving it changes nothing that matters, and it is most of the bins of a large map).
  double static_fraction = 1e-4;

  // Measurement model: a wrong placement lands anywhere within this many arc lengths of its arc.
  double outlier_range = 4.0;
  // A measurement on arc k explains places on arcs at most this many arcs before or after k.
  int reach = 3;

  // Report: the topological truth tolerates the neighbouring arc within this fraction of an arc from a node
  // (TopologicalTruthOptions::near_node_fraction).
  double node_tolerance = 0.15;
  // `tracking` needs this confidence ...
  double min_confidence = 0.95;
  // ... and a measurement of this frame that is an inlier with at least this probability.
  double min_inlier_probability = 0.5;

  bool Check(std::string* error = nullptr) const;
};

// The belief's answer for the current frame.
struct PlaceEstimate {
  arc_t arc = kInvalidArcId;  // the most likely arc; invalid before the map has arcs
  double along = 0.0;         // posterior mean of the position on `arc` (arc lengths)
  double sigma = 0.0;         // posterior standard deviation of that position
  double confidence = 0.0;    // P(camera on `arc`, or within node_tolerance of its ends on a neighbour)
  bool evidence = false;      // a measurement of this frame is an inlier
  bool tracking = false;      // confidence >= min_confidence and evidence
};

class PlaceBelief {
 public:
  explicit PlaceBelief(const Map& map, const PlaceBeliefOptions& options = {});

  // Uniform over the map, speed unknown (the start, before any evidence).
  void Reset();
  // Uniform over `arc` (a start arc the user gives), speed unknown.
  void ResetTo(arc_t arc);
  // The arcs of a planned route (navigation, nav/navigator.h): at a junction the motion model sends
  // planned_branch_probability of the mass into the planned branches (arcs continued past their end only; backward
  // motion stays equal). An empty list forgets the plan.
  void SetPlannedArcs(const std::vector<arc_t>& arcs);
  // Motion model over `frames` frames (1 per processed frame).
  void Predict(int frames = 1);
  // Bayes update with this frame's measurements (none: the prediction stands) and the estimate of this frame.
  // Returns each measurement's posterior probability of being an inlier. `frame` counts processed frames: with
  // evidence, the step of the estimated position since the last frame with evidence updates the speed.
  std::vector<double> Update(const std::vector<PlaceMeasurement>& measurements, size_t frame);
  const PlaceEstimate& estimate() const { return estimate_; }

  // The camera's speed along the graph, arc lengths of `arc` per frame; none while unknown.
  std::optional<double> SpeedOn(arc_t arc) const;
  // Probability mass on `arc` (all of its bins).
  double Mass(arc_t arc) const;
  // Probability that the camera is on `arc` or within node_tolerance of its ends on a neighbouring arc (what
  // PlaceEstimate::confidence gives for the most likely arc); in a gap between two pieces of the map, next to it
  // (the topological truth tolerates both arcs around the gap).
  double Confidence(arc_t arc) const;
  // Probability that `measurement` alone (its Gaussian; the outlier probability aside) puts the camera where
  // Confidence(arc) counts: on `arc` or within node_tolerance of its ends on its neighbours (the widest neighbour at a
  // junction). 0 when the measurement's arc is not within `reach` of `arc`.
  double MeasurementSupport(arc_t arc, const PlaceMeasurement& measurement) const;
  // The arc to report when the tracked features are on `tracked`: `tracked`, unless the most likely arc lies across
  // a gap between two pieces of the map from it (the last arc of one piece and the first of the next) and is more
  // likely correct (its confidence larger, and the estimate tracking). The truth tolerates both arcs only on the
  // stretch between the pieces, never on the other piece; the confidence of each counts the mass on that stretch,
  // so the one with more mass on its own side is the likelier right answer.
  arc_t ReportedArc(arc_t tracked) const;
  // Probability that the camera has left the map (more than an arc past a route's end or before its start).
  double OffMap() const { return off_map_; }
  // Length of `arc` in the belief's common unit.
  double ArcLength(arc_t arc) const;
  // Arcs that continue `arc` past its end / before its start (several at a junction; across the gap between two
  // pieces of a map teach left in pieces, the next piece's first arc / the previous piece's last one).
  const std::vector<arc_t>& Successors(arc_t arc) const;
  const std::vector<arc_t>& Predecessors(arc_t arc) const;
  // Signed distance along the graph from `from` to `to` (common units; positive forward), when `to` lies within
  // `max_arcs` arcs of `from`.
  std::optional<double> Distance(const GraphPlace& from, const GraphPlace& to, int max_arcs) const;
  const PlaceBeliefOptions& options() const { return options_; }

 private:
  struct ArcNode {
    arc_t id = kInvalidArcId;
    double length = 1.0;
    // The length the teach drive covered per frame on the arc (common units; a virtual arc: its real arc's).
    double teach_frame_length = 1.0;
    // A route's end has a virtual arc beyond it (and its start one before it), where a camera
    // past the last key-image (before the first) is; its mass counts for the real arc. -1 for a real arc.
    int virtual_of = -1;
    std::vector<int> virtual_children;
    std::vector<int> successors, predecessors;  // indices
    std::vector<double> successor_shares;       // of the mass continuing past the end, per successor (sum 1)
    std::vector<arc_t> successor_ids, predecessor_ids;
    // Where a piece of the map ends inside the drive: the first arc of the piece after the gap (index; -1: none),
    // and on that arc, the last arc of the piece before it.
    int across_gap_after = -1;
    int across_gap_before = -1;
  };
  int Index(arc_t arc) const;
  // Mass and confidence (see Mass, Confidence) of the real arc at index k.
  double MassAt(int k) const;
  double ConfidenceAt(int k) const;
  // Adds `mass` at position `along` of arc `index`, moved by a distance uniform in [low, high] (common units) along
  // the graph.
  void Deposit(std::vector<double>* target, int index, double along, double low, double high, double mass,
               int depth) const;
  void DepositAt(std::vector<double>* target, int index, double along, double mass) const;
  void DepositUniform(std::vector<double>* target, int index, double low, double high, double mass) const;
  // Offsets (common units) of the starts of the arcs within `reach` of arc `index`, relative to its start.
  void ReachableOffsets(int index, int reach, std::vector<std::pair<int, double>>* offsets) const;
  void ComputeEstimate();

  PlaceBeliefOptions options_;
  std::vector<ArcNode> arcs_;
  std::unordered_map<arc_t, int> index_;
  std::vector<double> mass_;  // arcs_.size() * bins
  std::vector<double> scratch_;
  mutable std::vector<double> diff_;  // per arc bins + 1: difference array of uniform deposits (Predict)
  // Probability that the camera is off the map: past the virtual arc beyond a route's end (before the one before its
  // start). Placements explain nothing there (outliers only); jumps bring it back.
  double off_map_ = 0.0;
  mutable double off_map_pending_ = 0.0;  // moved off the map in this prediction

  // Speed: the last estimated place with evidence and the steps since (common units per frame, newest first), and
  // the place the newest step started from with the frame that step was taken in (0: none), so that a second update
  // of that frame replaces the step.
  std::optional<GraphPlace> last_place_;
  size_t last_place_frame_ = 0;
  std::optional<GraphPlace> step_origin_;
  size_t step_origin_frame_ = 0;
  size_t newest_step_frame_ = 0;
  std::vector<double> steps_;
  std::optional<double> speed_;
  PlaceEstimate estimate_;
};

}  // namespace retrace
