#pragma once

// The Localizer's internal data, shared by its source files (localizer.cc: the per-frame flow and the belief;
// resumption.cc: predicted features and references; relocalization.cc: bootstrap and retrieval). Not part of the
// library's interface.

#include <memory>
#include <optional>
#include <unordered_map>
#include <vector>

#include <boost/container/flat_map.hpp>

#include "retrace/repeat/localizer.h"

namespace retrace {

struct Localizer::NodeData {
  const MapNode* node = nullptr;
  // The key-image's features, looked up by id only (never iterated): sorted arrays, 32 bytes an entry, where a hash
  // table's nodes and buckets took about twice that (the 4.8 km map's 1264 key-images hold about half a million).
  boost::container::flat_map<feature_t, Vector2d> positions;
  boost::container::flat_map<feature_t, Vector3d> bearings;
  std::unique_ptr<ImagePyramid> pyramid;
  // Relocalization key-points of the key-image (from its stored signature, or extracted).
  std::optional<WideBaselineFeatures> wide_baseline;
  std::unordered_map<feature_t, std::shared_ptr<const ReferencePatch>> references;  // null = cannot be cut
  // Frame counter of the last use of the derived data above (pyramid, wide_baseline, references).
  size_t last_used = 0;

  bool HasDerivedData() const { return pyramid || wide_baseline || !references.empty(); }
  void ReleaseDerivedData() {
    pyramid.reset();
    wide_baseline.reset();
    references.clear();
  }
};

// Whether `node` is one of the two key-images of `arc`.
inline bool HasEnd(const MapArc& arc, node_t node) { return node == arc.from || node == arc.to; }

struct Localizer::ArcData {
  const MapArc* arc = nullptr;
  std::unordered_map<feature_t, Vector3d> points;
  arc_t previous = kInvalidArcId;
  arc_t next = kInvalidArcId;
  // The planes at its key-images between which the camera is placed on it (placement.h).
  ArcBounds bounds;
  // Where no arc continues (previous) it, a gap teach could not bridge: the first (last) arc of the piece of the map
  // the teach drive made next (before), for the relocalization window (NodesNear); invalid at a route's ends.
  arc_t next_piece = kInvalidArcId;
  arc_t previous_piece = kInvalidArcId;
};

struct Localizer::CurrentGeometry {
  node_t node = kInvalidNodeId;
  bool estimated = false;
  TwoViewGeometry geometry;    // key_from... : a = key-image, b = current image
  std::vector<feature_t> ids;  // feature of each correspondence
  bool usable = false;
};

// The current camera in an arc's frame and scale, from which the arc's points are predicted (step 4 of the
// decomposed point transfer, Segvic 2009 §4.4). Built from a PointTransfer, or chained to a neighbouring arc through
// the relative scale stored at their common node when the current geometry shares too few features with that arc.
struct ArcPredictor {
  Rigid3d current_from_a;  // arc frame and scale
  Rigid3d b_from_a;        // the arc's geometry (|t| = 1)

  TransferredPoint Transfer(const Vector3d& point_in_a, const CameraModel& camera, ArcImage reference,
                            double margin) const;
};

// An arc of the current location with the predictor of its features (none: not predicted in this frame).
struct Localizer::RolePredictor {
  const ArcData* arc = nullptr;
  const std::optional<ArcPredictor>* transfer = nullptr;
  ArcRole role = ArcRole::kCurrent;
};

// This frame's placements of the camera on the current arc, as measurements of the belief.
struct Localizer::Placements {
  std::optional<PlaceMeasurement> pose;  // absolute pose in the arc's reconstruction
  std::optional<PlaceMeasurement> from;  // W_t:a through the decomposed transfer
  std::optional<PlaceMeasurement> to;    // W_t:b
  double sigma_p_from = 0.0, sigma_p_to = 0.0;
  // When the current arc gives none: the camera placed in a neighbouring arc's frame (absolute pose in its
  // reconstruction, else W_t:a / W_t:b through its decomposed transfer).
  std::optional<PlaceMeasurement> neighbour;
  // The lateral offset of the pose among these placements (pose or neighbour) unless it more likely collapsed than
  // not (CollapseProbability): entered in the lane when the belief takes the pose as right. Set only with `pose`, or
  // with `neighbour` when that is a pose, so the pose it belongs to is the frame's first measurement.
  std::optional<LaneEntry> lane;
};

namespace internal {
double Median(std::vector<double> values);
}  // namespace internal

}  // namespace retrace
