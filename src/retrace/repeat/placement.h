#pragma once

// Placing the current camera on an arc of the map (Segvic 2009 §5.2; design §6, §6.1).
//
// Every estimate of the current camera in an arc's frame — its absolute pose in the arc's reconstruction, or a
// current geometry W_t:a / W_t:b brought into the arc's frame and scale by the decomposed point transfer (§4.4) —
// places it on the arc: `along` is the projection of its centre on the arc (0 at the arc's first key-image a, 1 at
// its second b). The paper's decisions read that position: prudence (eqs. (7), (8)) and the topological transition
// (eq. (9)). retrace also turns each placement into a measurement of the place belief (belief.h) with a standard
// deviation and an outlier probability (PlacementModel): the absolute pose's from its covariance, the decomposed
// placements' from how far they were measured to lie from the truth.

#include "retrace/geometry/absolute_pose.h"
#include "retrace/geometry/two_view_geometry.h"
#include "retrace/map/map.h"
#include "retrace/repeat/belief.h"
#include "retrace/util/types.h"

namespace retrace {

// The centre of a camera in the world frame, from its pose cam_from_world (C = -Rᵀt).
Vector3d CameraCentre(const Rigid3d& cam_from_world);

// Where the current camera is relative to an arc, in the arc's frame and unit (|t| = 1).
struct ArcPosition {
  bool valid = false;
  double along = 0.0;             // (C_t - C_a) . (C_b - C_a): 0 at a, 1 at b
  double distance_to_from = 0.0;  // |C_t - C_a| (arc lengths)
  double distance_to_to = 0.0;    // |C_t - C_b|
};
// `current_from_a`: the current camera in the arc's frame and scale (PointTransfer::current_from_a()).
ArcPosition LocateOnArc(const Rigid3d& current_from_a, const Rigid3d& arc_b_from_a);
// A position known only along the arc (the belief's): distances measured along it.
ArcPosition AlongArc(double along);

// Prudence (Segvic 2009, eqs. (7), (8)): which neighbouring arcs may have features resumed at `position`.
struct ResumptionPolicy {
  bool next = false;
  bool previous = false;
};
ResumptionPolicy DecideResumption(const ArcPosition& position, double next_arc_ratio = 0.5,
                                  double previous_arc_ratio = 0.3);

// A current geometry (σ_p gating, Segvic 2009 §5.2.1): usable when it succeeded with σ_p below `max_sigma_p_px`.
bool GeometryUsable(const TwoViewGeometry& geometry, double max_sigma_p_px);

// Topological transition (Segvic 2009 §5.2.2, eq. (9)): forward (+1) when the camera centre has passed the plane
// through b's centre perpendicular to the arc's direction of travel, i.e. its projection on the arc lies beyond b
// (along > 1); backward (-1) when it lies more than `backward_margin` arc lengths behind a; else 0.
int DecideTransition(const ArcPosition& position, double backward_margin);

// Standard deviation (arc lengths) of the position along the arc given the covariance of the camera centre in the
// arc's frame and unit: σ² = dᵀ Σ d / |C_b|², d the arc's unit direction.
double AlongSigma(const Matrix3d& centre_covariance, const Rigid3d& arc_b_from_a);

// How reliable each kind of placement is, as a measurement of the place belief.
struct PlacementModel {
  // Absolute pose in the arc's reconstruction: σ from the pose's centre covariance (AlongSigma), which treats the
  // arc's points as exact; the points' own error (triangulated from two key-images) adds this much (arc lengths).
  // Measured over the seven simulated drives of scripts/sim-validation (README, about 1650 frames): the absolute
  // pose's placement error has a median of 0.005 and a 90th percentile of 0.025 arc lengths (a Gaussian with
  // σ = 0.015 has that percentile; 0.02 leaves a margin) ...
  double pose_sigma_floor = 0.02;
  // ... and 1.2 % of its placements were more than 0.15 arc lengths from the truth.
  double pose_outlier_probability = 0.02;
  // A current geometry W_t:a / W_t:b through the decomposed transfer: its scale and translation direction come
  // from fewer, often distant features. Its placement error: median 0.010, 90th percentile 0.10 (σ = 0.06), above
  // 0.15 in 7.0-7.7 % of the frames (same measurement).
  double geometry_sigma = 0.06;
  double geometry_outlier_probability = 0.08;
  // A key-image verified by wide-baseline matching (bootstrap, relocalization): the camera is near it, on the
  // side the sign test of eq. (9) says, within about half an arc; look-alike places verify too (when wrong, the
  // pick is any of the candidates: the outlier range is their number of arc lengths).
  double key_image_sigma = 0.5;
  double key_image_outlier_probability = 0.2;

  bool Check(std::string* error = nullptr) const;
};

// The measurements of the belief from one placement on `arc`.
PlaceMeasurement PoseMeasurement(arc_t arc, const ArcPosition& position, const AbsolutePose& pose,
                                 const Rigid3d& arc_b_from_a, const PlacementModel& model);
PlaceMeasurement GeometryMeasurement(arc_t arc, const ArcPosition& position, const PlacementModel& model);
// The camera is at key-image `node` of `arc` (its start or its end), picked among `candidates` key-images.
PlaceMeasurement KeyImageMeasurement(const MapArc& arc, node_t node, int candidates, const PlacementModel& model);

}  // namespace retrace
