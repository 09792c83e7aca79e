#pragma once

// Topological ground truth for repeat runs (design §9).
//
// The key-images of a linear route have true camera positions (their teach frames' ground-truth poses). The true
// position of a repeat frame is projected onto the polyline through them; the true arc is the segment it projects
// onto: between the last key-image passed and the next one (before the first key-image: the first arc; after the
// last: the last arc). A frame is correct when the estimated arc equals the true one; near a node (projection
// within `near_node_fraction` of the arc's length from one of its ends) the arc on the other side of that node is
// tolerated too (±1 near a node). Frames without an arc (lost / relocalizing) are counted as lost, never as
// correct.

#include <limits>
#include <string>
#include <vector>

#include "retrace/dataset/ground_truth.h"
#include "retrace/map/map.h"

namespace retrace {

// The arcs of a linear route in driving order (following each node's first outgoing arc from the node without an
// incoming one; a loop-closing arc is not followed twice). Empty when the map has no arcs.
std::vector<arc_t> RouteArcs(const Map& map);

struct TopologicalTruthOptions {
  // Near a node the neighbouring arc across that node is tolerated: within this fraction of the arc length.
  double near_node_fraction = 0.15;
};

// One repeat frame to evaluate: its index in the source sequence (to find its true pose) and the estimate.
struct RepeatRecord {
  size_t source_index = 0;
  bool localized = false;          // state tracking
  arc_t arc = kInvalidArcId;
};

struct FrameTruth {
  int true_arc_index = -1;       // index into RouteArcs
  int estimated_arc_index = -1;  // -1 when lost or the arc is not on the route
  int tolerated_arc_index = -1;  // the other arc tolerated near a node, -1 when none
  bool correct = false;
  bool lost = false;
  int error = 0;                 // |estimated - true| in arcs (0 when lost)
  // The true camera centre projected on the estimated arc (0 at its first key-image, 1 at its second; the repeat's
  // position_on_arc measured against the truth); NaN when lost.
  double true_position_on_arc = std::numeric_limits<double>::quiet_NaN();
};

struct TopologicalEvaluation {
  int frames = 0;
  int correct = 0;
  int lost = 0;
  int wrong = 0;          // localized on an arc that is neither true nor tolerated
  int wrong_by_two = 0;   // ... at least two arcs away from the true one
  std::vector<FrameTruth> per_frame;

  double FractionCorrect() const { return frames > 0 ? static_cast<double>(correct) / frames : 0.0; }
  double FractionLost() const { return frames > 0 ? static_cast<double>(lost) / frames : 0.0; }
  std::string Summary() const;
};

// `key_truth[i]` is the true pose of frame i of the teach sequence (key-images are found by
// MapNode::source_frame), `repeat_truth[i]` the true pose of frame i of the repeat sequence (RepeatRecord::
// source_index); both in the same world frame (for pseudo-repeat on one recording they are the same list). Throws
// std::invalid_argument when a frame has no pose.
TopologicalEvaluation EvaluateTopological(const Map& map, const std::vector<TimedPose>& key_truth,
                                          const std::vector<TimedPose>& repeat_truth,
                                          const std::vector<RepeatRecord>& records,
                                          const TopologicalTruthOptions& options = {});

}  // namespace retrace
