#pragma once

// Topological ground truth for repeat runs (design §9).
//
// The key-images have true camera positions (their teach frames' ground-truth poses); the route's arcs, in driving
// order (RouteArcs), are the segments of the polyline through them. The true arc of a repeat frame is the one
// between the last key-image it passed and the next one (before the first key-image: the first arc; after the last
// one of a linear route: the last arc).
//
// A map that teach left disconnected (a gap it could not verify: no arc between two key-images) has several pieces;
// the route takes them all, in the order the teach drive made them. Between two pieces the polyline goes on through
// the key-images the teach drive made there (in source_frame order; no arc of the route touches them): a stretch
// with no arc. A frame in such a stretch has no true arc (true_arc_index -1); the nearest arcs the map offers are
// tolerated, the one ending at the last key-image of the route it passed (the end of the piece before) and the one
// starting at the next (the start of the piece after); a frame reported on any other arc is wrong.
//
// The segment nearest to the frame's true position is not always its true arc: a route may cross or retrace itself,
// and a frame driving a little to the side of the taught path can then be nearer to a part of the route driven at
// another time, many arcs away:
//
//      pass 2  \   /  pass 1         figure-8 crossing: near X a frame of pass 1 can be nearer to a segment of
//               \ /                  pass 2 (and the other way round) although the two passes cross at an acute
//                X                   angle;
//               / \                  street driven out and back:  ---->----  a frame of the way back
//                                                                 ----<----  can be nearer to the way out.
//
// So the truth follows the drive (design §9: "only onto the parts travelled in the same direction and in order along
// the drive"). The true segments of all records are labelled together as the best path of a hidden-Markov model,
// found by dynamic programming (Viterbi) over (record, segment):
//  - Heading. A segment is a candidate for a frame only when the camera's optical axis (z axis of world_from_cam)
//    is less than `max_heading_difference_deg` from the segment's direction of travel (first key-image to second).
//    The optical axis rather than the direction of motion between records: it is defined when the camera stands
//    still, in the first record and across dropped frames, free of the ground truth's jitter at low speed, and for
//    the forward-looking cameras of teach and repeat it is the direction of travel (reversing is left to the order
//    rule). This alone separates the two directions of a street driven out and back.
//  - Order. Between consecutive records, the position along the route (arc length of the clamped projection onto
//    the segment) may advance by at most (1 + speed_tolerance) times the distance the camera travelled, and go back
//    only by what it travelled against its optical axis (a reversing camera), by (1 + speed_tolerance) times that.
//    Both allow `order_slack` plus the two positions' distances from their segments: the projection of a camera
//    beside the route jumps at the corners of the polyline. This separates the passes of a crossing, the laps of a
//    circular route and an out-and-back street at its turning point.
//  - Cost of a path: the sum over records of the distance from the true position to its segment, plus
//    `violation_cost` for each record whose segment fails the heading test and for each step that breaks the order
//    rule. The rules are soft only so that a labelling always exists (a gap in the ground truth, a camera looking
//    backwards): with the default cost, one broken rule outweighs a kilometre of distance summed over the records.
//  - Records are taken in processing order; frames may be dropped (the order rule scales with the distance
//    travelled) and the repeat may start anywhere on the route (the first record's segment is free).
//  - Work: records x segments^2 comparisons at most (pruned by cost); 15 ms for 735 records on 127 arcs.
// Where the nearest segments obey both rules (a route that neither crosses nor retraces itself, a repeat close to it)
// they are the labels, as with the former nearest-segment rule.
//
// The labels are segments of the polyline: arcs, and the parts of the stretches between pieces. A circular route
// (RouteArcs ends with the teacher's loop-closing arc from the last key-image L back to an early one, c) is unrolled
// for as many laps as the repeat can drive: arcs 0 .. n-1, loop, c .. n-1, loop, c ... A frame past L is on the loop
// arc and then on the arcs after c again, never on the first lap's arcs at the same place. L and c are about the same
// place: the loop arc spans the signed gap from L to c along the direction of travel into L, and when c is behind L
// the later laps enter arc c where L is (a frame that has not passed L is on the arc into L, one that has is on arc
// c).
//
// A frame is correct when the estimated arc equals the true one; near a node N the arc on the other side of N along
// the drive is tolerated too (±1 near a node; never across a stretch between pieces). With f = `near_node_fraction`,
// a frame on arc k is near N, one of k's key-images, when
//  - its raw projection on arc k is within f of k's length from N, or
//  - it is abeam N: its true position p is less than f times the length of the shorter of the two arcs meeting at N
//    from N along the route's direction there, |(p - N) . t| with t the mean of the two arcs' unit directions, and
//    it projects onto N's half of both arcs (in a hairpin t crosses both arcs, and a frame halfway along one of them
//    is not near N). On a straight route this is the projection rule on the shorter arc. In a turn a repeat driven
//    beside the taught path passes N away from its projections on the arcs: 1 m inside a turn of 22 degrees
//    (validation speed15, frame 66) the labelling puts a frame abeam node 11 on arc 11 at 0.18 of it, and arc 10 was
//    not tolerated. Not the plain distance |p - N|: it includes the lateral offset, and with key-images 2-4 m apart
//    a camera 1 m beside the path is 0.3-0.65 arc lengths from every node (that frame: 0.95 m from node 11, 0.29 and
//    0.47 of the two arcs' lengths; abeam 0.16 m, 0.08 of the shorter).
// The error counts steps along the drive between the estimated arc and the true one, either way (around the cycle on
// a circular route): one per arc and one per stretch between pieces (in a stretch, an arc beside it is 1 off; on the
// first arc of a piece, the last arc of the piece before is 2 off). Frames without an arc (lost / relocalizing) are
// counted as lost, never as correct.

#include <limits>
#include <string>
#include <vector>

#include "retrace/dataset/ground_truth.h"
#include "retrace/map/map.h"

namespace retrace {

// The arcs of a route in driving order, piece after piece: from each node with an outgoing (non-loop) arc and no
// incoming one, in teach order (MapNode::source_frame), each node's first unused outgoing arc that is not a
// loop-closing one. Where an arc does not start at the node the one before it ended at, the route goes on after a
// stretch without arcs (a disconnected map). A circular route (the teacher's loop-closing arc, kind "loop", from the
// last node back to a node of the route, or else from a key-image teach made after the last node) ends with that
// arc, once. Empty when the map has no arcs.
std::vector<arc_t> RouteArcs(const Map& map);

struct TopologicalTruthOptions {
  // Near a node the neighbouring arc across that node is tolerated: within this fraction of the arc length (of the
  // true arc by the projection on it; of the shorter of the two arcs abeam the node).
  double near_node_fraction = 0.15;
  // Heading: a segment is a candidate only when the camera's optical axis is less than this from its direction.
  double max_heading_difference_deg = 90.0;
  // Order: the position along the route may advance by (1 + this) times the distance travelled between records
  // (a semicircle is π/2 times its chord, so dropped frames in a U-turn still fit).
  double speed_tolerance = 1.0;
  // Order: allowance on each step, in the units of the ground truth (metres for KITTI and the simulator).
  double order_slack = 1.0;
  // Cost of a heading mismatch or a broken order rule, in the units of the ground truth (an equivalent distance).
  double violation_cost = 1000.0;

  bool Check() const {
    return near_node_fraction >= 0.0 && near_node_fraction <= 0.5 && max_heading_difference_deg > 0.0 &&
           max_heading_difference_deg <= 180.0 && speed_tolerance >= 0.0 && order_slack >= 0.0 && violation_cost > 0.0;
  }
};

// One repeat frame to evaluate: its index in the source sequence (to find its true pose) and the estimate.
struct RepeatRecord {
  size_t source_index = 0;
  bool localized = false;  // state tracking
  arc_t arc = kInvalidArcId;
};

struct FrameTruth {
  int true_arc_index = -1;       // index into RouteArcs; -1 in a stretch between two pieces of the route
  int estimated_arc_index = -1;  // -1 when lost or the arc is not on the route
  int tolerated_arc_index = -1;  // the other arc tolerated near a node (in a stretch: the arc before it), -1 if none
  int tolerated_after_arc_index = -1;  // in a stretch between two pieces: the arc after it, else -1
  bool correct = false;
  bool lost = false;
  // Steps along the drive between estimated and true (arcs, and stretches between pieces); 0 when lost, the route's
  // number of steps when the arc is off the route.
  int error = 0;
  // The true camera centre projected on the estimated arc (0 at its first key-image, 1 at its second; the repeat's
  // position_on_arc measured against the truth); NaN when lost.
  double true_position_on_arc = std::numeric_limits<double>::quiet_NaN();
};

struct TopologicalEvaluation {
  int frames = 0;
  int correct = 0;
  int lost = 0;
  int wrong = 0;         // localized on an arc that is neither true nor tolerated
  int wrong_by_two = 0;  // ... at least two arcs away from the true one
  std::vector<FrameTruth> per_frame;

  double FractionCorrect() const { return frames > 0 ? static_cast<double>(correct) / frames : 0.0; }
  double FractionLost() const { return frames > 0 ? static_cast<double>(lost) / frames : 0.0; }
  std::string Summary() const;
};

// `key_truth[i]` is the true pose of frame i of the teach sequence (key-images are found by
// MapNode::source_frame), `repeat_truth[i]` the true pose of frame i of the repeat sequence (RepeatRecord::
// source_index); both in the same world frame (for pseudo-repeat on one recording they are the same list).
// `records` in processing order. Throws std::invalid_argument when a frame has no pose, the map has no route or the
// options fail Check().
TopologicalEvaluation EvaluateTopological(const Map& map, const std::vector<TimedPose>& key_truth,
                                          const std::vector<TimedPose>& repeat_truth,
                                          const std::vector<RepeatRecord>& records,
                                          const TopologicalTruthOptions& options = {});

// Whether a frame localized on `arc` is right by its truth `truth` (correct as EvaluateTopological counts it: the
// true arc or one tolerated near a node or a stretch; an arc off the route is wrong). For frames evaluated one by one
// or a few at a time (kidnapped starts), take `truth` from an evaluation of the whole drive: a few frames evaluated
// alone have no order along the drive, and on a route that crosses or retraces itself they may be judged against
// the other pass.
bool IsCorrectEstimate(const FrameTruth& truth, const std::vector<arc_t>& route, arc_t arc);

// The true pose of a camera relative to the taught camera path (path tracking, taught_path.h): the taught camera
// centres `taught[first..last]` as a polyline on the ground plane of the world frame — x-z, y pointing down, as the
// simulator's world and (nearly) KITTI's first camera — and the camera at `world_from_cam`. Restricting the polyline
// to the taught frames around the arc at hand keeps a route that crosses itself from being measured against the
// wrong pass.
struct PathTruth {
  bool valid = false;
  double distance_m = 0.0;         // distance from the path (at a vertex larger than |lateral_m|)
  double lateral_m = 0.0;          // signed distance from the path, positive to the right in the direction of travel
  double heading_error_rad = 0.0;  // optical axis against the path's tangent, positive looking right of the path
  double along_index = 0.0;        // where the nearest point lies (taught frame index, fractional)
};
PathTruth TruthAgainstTaughtPath(const Rigid3d& world_from_cam, const std::vector<TimedPose>& taught, size_t first,
                                 size_t last);

}  // namespace retrace
