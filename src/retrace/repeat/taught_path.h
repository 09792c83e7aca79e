#pragma once

// Where the camera is relative to the taught path, in metres (path tracking; Segvic 2009 §6.3 steers by the image
// alone, this gives a path-tracking law what it needs).
//
// The taught path is the camera's path during teach. Locally it passes through the centres of the key-images of the
// current arc (a, b), of the previous arc's first key-image and of the next arc's last one, all expressed in the
// current arc's frame (key-image a's camera). Each arc has its own unit; the metric scale of an arc comes from the
// camera's height above the ground, which the user knows: the ground plane between the arc's key-images
// (geometry/ground_plane.h) puts camera b at distance d (arc units) above the road, so metres per unit = h / d. A
// camera fixed on a vehicle keeps its attitude to the road under it, so the ground's normal in the camera's frame is
// estimated once from arcs spread over the map (CommonGroundNormal), and each arc fits only d. One arc's fit is
// wrong now and then (10 % of the arcs of the tuning and town drives, by factors of 0.1-15: a road without texture,
// a crossing's stripes, a car ahead), and wrong fits come in runs where the road does; the relative scales the map
// stores at its nodes are good to 1-1.5 %. So each arc's scale combines the fits of the arcs within `scale_window`
// of it, carried into its unit through the node scales, by the robust model of CombineArcScales below.
//
// On the ground plane (normal n of the arc's frame, pointing down) the path between a and b is a cubic Hermite
// curve whose tangents follow the turn each arc measured (KeyImageTangents below), which follows the curvature of a
// turn where the chord a-b would cut it (a 4 m chord of a 7 m radius turn lies 0.29 m inside it). Catmull-Rom
// tangents (from the previous to the next key-image) did that only where the neighbouring arcs turn alike: a 27°
// turn within one 6.7 m arc between straight ones bulged 0.2 m of the drive's 0.58 (README).
// The camera centre (its absolute pose in the arc's reconstruction) is projected on the curves of the previous,
// current and next arcs; the nearest point gives
//  - lateral offset: signed distance from the path, positive to the right in the direction of travel;
//  - heading error: the angle from the taught camera's direction of travel there to the camera's optical axis (both
//    on the ground plane), positive when the camera looks to the right of the path. The direction of travel is the
//    curve's tangent in turns and, between key-images whose arcs are straight, their optical axes turned by the
//    vehicle's travel model (TravelModel below), which the chords of forward motion get wrong by degrees now and then;
//  - along: distance along the path from the current arc's key-image a (negative before it, beyond the arc's length
//    after b), and to_next: distance left to b;
//  - the path's curvature there and the largest curvature within the next arc (1/m, positive turning left).

#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <unordered_map>

#include "retrace/camera/camera_model.h"
#include "retrace/geometry/ground_plane.h"
#include "retrace/map/map.h"
#include "retrace/util/types.h"

namespace retrace {

struct TaughtPathOptions {
  // Height of the camera's centre above the ground (m), as mounted on the robot. 0: unknown, no metric path.
  double camera_height = 0.0;
  // The ground plane fits (geometry/ground_plane.h); the normal is estimated here unless set.
  GroundPlaneOptions ground;
  // Arcs (spread evenly over the map) whose free ground planes give the common normal.
  int normal_arcs = 15;
  // An arc's scale combines the ground planes of the arcs up to this many before and after it (CombineArcScales).
  // A carried scale gains relative_scale_sigma² of variance per node, so far arcs weigh little: 8 arcs away the
  // node scales add 4 % against the fit's 3 %.
  int scale_window = 8;
  // The scale model (natural log of metres per unit), see CombineArcScales. The standard deviation of one node's
  // relative scale (measured 1.0-1.4 % against ground truth on the 19 tuning and town drives of the validation
  // matrix), of a right ground fit (the spread of the right fits there: 2-3 %; the fit's own σ from the normal
  // equations is used when larger), and the probability that a fit is wrong (10 % there).
  double relative_scale_sigma = 0.015;
  double ground_scale_sigma = 0.03;
  double ground_outlier_probability = 0.15;
  // The taught path's direction where the camera is, as an angle (radians): it follows the arcs' two-view
  // translations, whose direction was off by 0.24° (median; 90th percentile 0.75°) on the tuning and town drives of
  // the validation matrix (README, "Where the car is, in metres") — a Gaussian with that median has σ 0.36°. It adds
  // to the pose's own in heading_sigma_rad where the curve's tangent is the reference (travel_sigma_rad elsewhere).
  double tangent_sigma_rad = 0.006;
  // The heading error's reference on straights: the direction the taught camera travelled at each key-image, from
  // its optical axis and the vehicle's travel model (FitTravelModel) fitted over the arcs up to `travel_window` before
  // and after the current one (their lengths carried into its unit through the node scales: 30 arcs away about 8 %
  // off, σ_r √30, which the medians absorb). 0: the curve's tangents everywhere, as before 2026-12-06 — for a robot
  // that can move sideways (holonomic), which the model does not describe.
  int travel_window = 30;
  // An arc is straight when it turns less than this (radians, 2°): the key-images between two straight arcs take the
  // model's direction. The arcs turning more give the model's camera_ahead.
  double travel_min_turn_rad = 0.035;
  // The travel model's direction as an angle (radians) where it is the reference, in place of tangent_sigma_rad in
  // heading_sigma_rad, when the model's own (TravelModel::DirectionSigma, from the spread of the arcs it was fitted
  // to) cannot be measured (fewer than 5 arcs). Between key-images of straight arcs the direction was 0.03° off at the
  // median on the validation matrix's simulated maps and 0.14° on kitti07's (24 key-images; the truth there from the
  // poses of the frames on either side): a Gaussian with the larger median has σ 0.21°. That constant, used
  // everywhere until 2026-12-07, was about five times the σ of the simulated maps' errors, where the model's own σ
  // is about 0.03° (docs/path-tracking.md, "The heading's σ from the map").
  double travel_sigma_rad = 0.0036;

  bool Check(std::string* error = nullptr) const;
};

// The camera relative to the taught path (see the comment at the top).
struct PathPose {
  bool valid = false;
  double lateral_m = 0.0;
  double heading_error_rad = 0.0;
  double along_m = 0.0;
  double to_next_m = 0.0;
  double arc_length_m = 0.0;       // the reported arc's length along the path
  double curvature = 0.0;          // 1/m, positive to the left, at the nearest point of the path
  double curvature_ahead = 0.0;    // the largest |curvature| (with its sign) from here to the end of the next arc
  // Standard deviations (first order): the lateral offset's from the camera centre's covariance and the scale's.
  double lateral_sigma_m = 0.0;
  double scale_sigma = 0.0;        // relative standard deviation of the arc's metric scale
  // The heading error's (the path's direction, TaughtPathOptions::tangent_sigma_rad, and the rotation's covariance
  // about the ground's normal) and along_m's (the centre's covariance along the path, and the scale's).
  double heading_sigma_rad = 0.0;
  double along_sigma_m = 0.0;
  // The localizer reports in lateral_m / lateral_sigma_m the recent frames' offsets combined
  // (LocalizerOptions::lateral_filter), and this frame's own here (TaughtPath::Locate: the same as lateral_m).
  double frame_lateral_m = 0.0;
  double frame_lateral_sigma_m = 0.0;
  // How the pose's heading error moves with its lateral offset's error (rad/m): the regression cov(ψ, e) / var(e)
  // of the two through the pose's covariance (the centre's, the rotation's and their cross-covariance; not the
  // scale's or the path's). A pose fitted to points at about one depth Z trades a sideways shift for a turn that
  // keeps them in view, ≈ −1 / Z (the bas-relief ambiguity): given a better offset e' than the frame's, the heading
  // is best taken as ψ + heading_per_lateral · (e' − frame_lateral_m). 0 when unknown.
  double heading_per_lateral = 0.0;
};

// The covariance of an absolute pose in an arc's reconstruction (AbsolutePose, geometry/absolute_pose.h): of the
// camera centre (arc frame and unit²), of its rotation δω in its own frame (radians²), and their cross-covariance
// E[δω δCᵀ].
struct PoseCovariance {
  Matrix3d centre = Matrix3d::Zero();
  Matrix3d rotation = Matrix3d::Zero();
  Matrix3d rotation_centre = Matrix3d::Zero();
};

// One arc's ground-plane scale carried into the unit of the arc being scaled (through `steps` node scales, on one
// side of it).
struct CarriedScale {
  double log_metres_per_unit = 0.0;  // natural log, in the unit of the arc being scaled
  int side = 0;                      // 0: the arc itself; +1: an arc after it; -1: an arc before it
  int steps = 0;                     // node scales crossed (0 for the arc itself)
  double fit_sigma = 0.0;            // relative standard deviation of the fit itself (optimistic)
};

struct CombinedScale {
  bool valid = false;
  double metres_per_unit = 0.0;
  double sigma = 0.0;  // relative standard deviation (posterior, with the fits judged right)
  int inliers = 0;     // fits judged right (responsibility > 0.5)
};

// The metric scale of one arc from the carried scales of the arcs around it (CombineCarriedObservations,
// util/robust_random_walk.h): in logs, x the arc's scale, each node scale on the way adds ε ~ N(0, σ_r²) (v_j = σ_r²
// · steps), a right fit has σ_j = max(σ_g, its own σ), and a wrong one is uniform over the range of log-scales the
// ground search spans (log(max_distance / min_distance)).
CombinedScale CombineArcScales(const std::vector<CarriedScale>& scales, const TaughtPathOptions& options);

// Unit tangents of the taught path at its key-images, in ground-plane coordinates (`centres`; `headings` are the
// key-images' optical axes on the ground plane, any length). Each arc between two key-images is taken as a circle
// through both that turns by the angle between their headings — a camera fixed on the vehicle turns with its
// direction of travel, whatever its mount's yaw — so its tangents lie at ∓ Δψ / 2 from the chord; at a key-image
// between two arcs the two circles' tangents are averaged. Exact on a circle however the key-images are spaced.
std::vector<Vector2d> KeyImageTangents(const std::vector<Vector2d>& centres, const std::vector<Vector2d>& headings);

// How a camera fixed on a vehicle moves relative to its optical axis: on the ground plane its direction of travel is
// turned from the axis by β = atan(camera_ahead · κ) - mount_yaw (positive to the left), κ the path's curvature
// (positive turning left). A car (or a differential-drive robot) turns about a point on its rear axle; a camera
// `camera_ahead` in front of it moves sideways by camera_ahead · κ per unit driven (rigid-body kinematics), and a
// camera yawed on its mount by `mount_yaw` looks that much to the left of the vehicle. Two constants of the vehicle,
// fitted over many arcs (FitTravelModel), from which each key-image's direction of travel follows from its own axis
// and the curvature there. Why: in forward motion the two-view geometry determines the translation's direction (the
// focus of expansion) worst of all, and the chords between key-images, which the taught path's tangents follow, were
// off by 3° over five straight arcs of long124 (the car then steered 0.3 m off). Against the teach poses of the
// validation matrix's simulated maps (between the key-images, median / 90th / 99th percentile): on straight arcs the
// chords' tangents 0.16 / 0.49 / 1.30°, the model's directions 0.04 / 0.10 / 0.26°; next to a turn the chords
// 0.49 / 1.59 / 3.69°, the model 0.93 / 2.82 / 5.11° — there the curvature changes within an arc, which the curve
// through the key-images follows and the model's curvatures at the key-images do not. So TaughtPath::Locate takes
// the model's direction on straights and the curve's tangent in turns (docs/path-tracking.md, "The direction of
// travel from the vehicle's kinematics").
struct TravelModel {
  bool valid = false;
  double mount_yaw = 0.0;     // radians, positive to the left
  double camera_ahead = 0.0;  // in the unit of the lengths FitTravelModel was given
  int straight_arcs = 0;      // arcs turning less than the fit's min_turn
  int turning_arcs = 0;
  // The standard error of mount_yaw (radians): the median of n votes spread by σ (1.4826 times their median absolute
  // deviation) has √(π/2) σ / √n. NaN with fewer than kMinVotesForSigma votes (no spread to measure).
  double mount_yaw_sigma = std::numeric_limits<double>::quiet_NaN();
  static constexpr int kMinVotesForSigma = 5;
  // The spread (robust σ, 1 / the fit's unit) of the straight arcs' curvatures, turn / length (0 with fewer than
  // kMinVotesForSigma): the curvature the direction of travel is taken at errs by about this on a straight.
  double curvature_sigma = 0.0;
  // The standard deviation of the direction of travel on a straight (radians): the mount's error and the curvature's
  // through camera_ahead; NaN where mount_yaw_sigma is.
  double DirectionSigma() const { return std::hypot(mount_yaw_sigma, camera_ahead * curvature_sigma); }
  // β at curvature κ (1 / the fit's unit).
  double TravelAngle(double curvature) const { return std::atan(camera_ahead * curvature) - mount_yaw; }
};

// One arc as the travel model sees it, on the ground plane of its key-image a: the angle of its chord from a's
// optical axis minus half its turn (a circle through a and b has its tangents there: the mean of β at a and b), the
// turn from a's axis to b's (radians, positive left) and the chord's length.
struct ArcTravel {
  double chord_angle = 0.0;
  double turn = 0.0;
  double length = 0.0;
};

// The travel model's two constants from arcs, by medians (robust to the chords the geometry got wrong): mount_yaw
// from the arcs turning less than `min_turn` (all arcs when there are none), camera_ahead from the others as
// tan(β + mount_yaw) / κ with κ = turn / length, alternated three times with mount_yaw from every arc. No turning
// arc: camera_ahead 0 (it then matters little). Invalid without arcs.
TravelModel FitTravelModel(const std::vector<ArcTravel>& arcs, double min_turn);

class TaughtPath {
 public:
  // `map` must hold its key-images and outlive this object; `camera` images the key-images. Throws
  // std::invalid_argument for options that fail Check().
  TaughtPath(const Map& map, const CameraModel& camera, const TaughtPathOptions& options);
  ~TaughtPath();

  bool enabled() const { return options_.camera_height > 0; }
  // The ground's normal in the camera's frame (estimated at the first call); none when too few arcs show a ground.
  const std::optional<Vector3d>& GroundNormal();
  // Metres per unit of `arc` (the median over its window); none when no arc of the window has a ground plane.
  std::optional<double> MetresPerUnit(arc_t arc);
  // The ground plane of `arc` alone (the arc's MapArc::ground_fit when it has one, else fitted between its
  // key-images, ≈ 5-8 ms at 320x240); distance_b 0 when there is none. What teach stores (StoreGroundFits).
  MapArc::GroundFit GroundFit(arc_t arc);
  // The travel model over every arc of the map with a metric scale, camera_ahead in metres: what teach reports of the
  // rig (a camera 1-2 m ahead of a car's rear axle; far off, or turning the wrong way, says the robot is not
  // car-like and --travel-window 0 fits it better). Invalid without a metric path.
  TravelModel MapTravelModel();

  // The camera placed at `current_from_a` in the reconstruction of `pose_arc` (its frame and unit), relative to the
  // taught path around `reported_arc` (pose_arc or one of its neighbours). `covariance` (may be null: the pose taken
  // as exact) gives lateral_sigma_m, along_sigma_m, heading_sigma_rad and heading_per_lateral. Invalid when disabled
  // or no metric scale is known.
  PathPose Locate(arc_t pose_arc, const Rigid3d& current_from_a, const PoseCovariance* covariance, arc_t reported_arc);

 private:
  struct ArcGround;
  const ArcGround& Ground(arc_t arc);
  // The travel model over the arcs within options_.travel_window of `arc`, lengths in `arc`'s unit (cached).
  const TravelModel& Travel(const MapArc& arc);
  // One arc as the travel model sees it, its chord `unit_length` long per unit. Needs the ground's normal.
  ArcTravel MeasureTravel(const MapArc& arc, double unit_length) const;
  // Calls visit(neighbour, log_unit_ratio, side, steps) for the arcs up to `window` after (side +1) and before (-1)
  // `arc` along the route, while the nodes' relative scales chain them: a length in units of `arc` times
  // exp(log_unit_ratio) is that length in units of the neighbour.
  template <typename Visit>
  void ForEachNeighbour(const MapArc& arc, int window, Visit&& visit) const;
  const MapArc* Next(const MapArc& arc) const;
  const MapArc* Previous(const MapArc& arc) const;

  const Map& map_;
  std::unique_ptr<CameraModel> camera_;
  TaughtPathOptions options_;
  bool normal_estimated_ = false;
  std::optional<Vector3d> normal_;
  std::unordered_map<arc_t, std::unique_ptr<ArcGround>> grounds_;
  std::unordered_map<arc_t, TravelModel> travel_;
};

}  // namespace retrace
