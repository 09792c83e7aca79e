#pragma once

// Placing the current camera on an arc of the map (Segvic 2009 §5.2; design §6, §6.1).
//
// Every estimate of the current camera in an arc's frame — its absolute pose in the arc's reconstruction, or a
// current geometry W_t:a / W_t:b brought into the arc's frame and scale by the decomposed point transfer (§4.4) —
// places it on the arc: `along` is where its centre lies between the planes that bound the arc (below; 0 at the
// arc's first key-image a, 1 at its second b). The paper's decisions read that position: prudence (eqs. (7), (8)) and
// the topological transition (eq. (9)). retrace also turns each placement into a measurement of the place belief
// (belief.h) with a standard deviation and an outlier probability (PlacementModel): the absolute pose's from its
// covariance, the decomposed placements' from how far they were measured to lie from the truth.
//
// The planes that bound an arc. Eq. (9) ends arc (a, b) at the plane through b perpendicular to the arc; the next
// arc (b, c) starts at the plane through b perpendicular to IT. In a turn the two planes differ by the turn's angle,
// and a camera driving beside the taught path meets them at different times: with a lateral offset d and a turn of θ
// at b, d·tan(θ/2) apart (3 m outside a 30° turn: 0.8 m, a third of an arc of 2.4 m). Its projection on (a, b) then
// says `along` > 1 while its projection on (b, c) still says < 0, or the other way round on the inside, and the
// placements of two neighbouring arcs disagree about the same camera. retrace therefore bounds each arc at the
// BISECTING planes of its nodes (ArcBounds): at b, the plane through b whose normal is the mean of the two arcs' unit
// directions, which is the set of points at equal distance from the two arcs' lines — where the nearest taught
// segment, the topological truth of repeat/evaluation.h, changes from (a, b) to (b, c). With s_a, s_b the signed
// distances of the camera centre from the planes at a and b (arc lengths), `along` is s_a / (s_a − s_b) between
// them: 0 on a's plane, 1 on b's. Before a's plane and past b's it is the distance from that plane measured along
// the arc, s / (d · n) (d the arc's direction, n the plane's normal): the arc's own scale carries on, so a camera
// that passed several key-images in one frame is placed several arc lengths ahead. Far beside a turn, where the two
// planes meet (s_a < 0 < s_b), and with the paper's planes (a straight route, a route's end, a junction, a link) it
// is the projection of the centre on the arc. On the taught path all of these agree at both key-images.

#include <vector>

#include "retrace/geometry/absolute_pose.h"
#include "retrace/geometry/point_transfer.h"
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
// The planes at an arc's two key-images, in the arc's frame (a's camera frame): unit normals pointing along the
// direction of travel, through C_a and C_b. Default: both perpendicular to the arc (eq. (9) as the paper).
struct ArcBounds {
  Vector3d normal_at_from = Vector3d::Zero();  // zero: the arc's own direction
  Vector3d normal_at_to = Vector3d::Zero();
};
// The bisecting planes of arc (a, b) given the arc before it, z -> a (`previous_a_from_z`, its to_from_from), and
// the arc after it, b -> c (`next_c_from_b`); null for a route's end, a junction or a link (two images of one place
// have no direction of travel), which keep the perpendicular plane. A reversal (the two directions more than
// `max_turn_deg` apart) keeps it too: the bisector of a hairpin runs along the road.
ArcBounds BisectingBounds(const Rigid3d& arc_b_from_a, const Rigid3d* previous_a_from_z, const Rigid3d* next_c_from_b,
                          double max_turn_deg = 120.0);

// `current_from_a`: the current camera in the arc's frame and scale (PointTransfer::current_from_a()). `along` is
// measured between the planes of `bounds` (see above); where the camera is so far beside a sharp turn that the two
// planes meet before it (the denominator s_a − s_b below a quarter of the arc), the chord projection is used.
ArcPosition LocateOnArc(const Rigid3d& current_from_a, const Rigid3d& arc_b_from_a,
                        const ArcBounds& bounds = ArcBounds());
// Whether a camera centre `centre` (in the arc's frame, at any scale: a unit-length W_t:a will do) lies on or in
// front of the plane through a that starts the arc (`bounds`' plane at a): the sign test of eq. (9) at a, which
// needs no scale.
bool InFrontOfStartPlane(const Vector3d& centre, const Rigid3d& arc_b_from_a, const ArcBounds& bounds = ArcBounds());
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
// through b's centre that ends the arc (perpendicular to the arc's direction of travel in the paper, the bisecting
// plane with ArcBounds), i.e. along > 1; backward (-1) when it lies more than `backward_margin` arc lengths behind a;
// else 0.
int DecideTransition(const ArcPosition& position, double backward_margin);

// Standard deviation (arc lengths) of the position along the arc given the covariance of the camera centre C in the
// arc's frame and unit: σ² = gᵀ Σ g with g the gradient of `along` at C — d / |C_b| for the perpendicular planes (d
// the arc's unit direction), (s_a n_b − s_b n_a) / (s_a − s_b)² between bisecting planes.
double AlongSigma(const Matrix3d& centre_covariance, const Rigid3d& arc_b_from_a,
                  const Vector3d& centre = Vector3d::Zero(), const ArcBounds& bounds = ArcBounds());

// The current camera placed by the key-images a bootstrap verified by wide-baseline matching (Segvic 2009 §3.3), for
// when too few mapped features align to place it by the arc's reconstruction: 2.5 m beside the taught path, under
// another sun, their windows, cut where the teach drive was, no longer match (validation drive beside111: 2-7 of
// about 200 located for 30 frames in a row while three or four key-images of the place verified with 50-100 inliers
// each). The key-images of an arc and of its neighbours have known poses in the arc's frame, so a key-point of the
// frame matched in two or more of them is a point that can be triangulated there (Hartley & Zisserman 2003, §12.2),
// and the camera resected from such points as from the arc's own. (Each key-image's relative pose alone gives the
// direction towards the camera, not how far: intersecting those directions was tried first and failed — beside
// facades the essential matrix trades that direction for a turn, 10-50° off.)
struct KeyImageMatches {
  Rigid3d key_from_arc;                    // the key-image's pose in the arc's frame and unit
  std::vector<int> current_keypoints;      // per match: the frame's key-point (the same index in every key-image)
  std::vector<Vector3d> key_bearings;      // per match: its bearing in the key-image
  std::vector<Vector3d> current_bearings;  // ... and in the frame
};
// Each key-point of the frame matched in two or more of `views` is triangulated (TriangulateMidpoint) from the two
// whose rays meet at the widest angle and kept when it lies in front of, and within `max_angle_rad` of the ray of,
// every key-image that matched it; the camera is resected from those points in the arc's frame (EstimateAbsolutePose,
// each point weighted by its two views' covariance, TwoViewPointCovariance). `num_points` (optional): the points.
AbsolutePose ResectFromKeyImages(const std::vector<KeyImageMatches>& views, double max_angle_rad,
                                 double focal_length_px, const AbsolutePoseOptions& options, int* num_points = nullptr);

// How reliable each kind of placement is, as a measurement of the place belief.
struct PlacementModel {
  // Absolute pose in the arc's reconstruction: σ from the pose's centre covariance (AlongSigma), which treats the
  // arc's points as exact; the points' own error (triangulated from two key-images) adds this much (arc lengths).
  // Measured over the seven simulated drives of scripts/sim-validation (README, about 1650 frames): the absolute
  // pose's placement error has a median of 0.005 and a 90th percentile of 0.025 arc lengths (a Gaussian with
  // σ = 0.015 has that percentile; 0.02 leaves a margin) ...
  double pose_sigma_floor = 0.02;
  // ... and 1.2 % of its placements were more than 0.15 arc lengths from the truth — the more often the fewer inliers
  // the pose rests on. Over the validation matrix (85 drives, the 19 660 frames reported tracking with a pose and no
  // transition; run.csv's position_via_pose and pose_inliers against run.truth.csv, 2026-12-07): 12 % with 6-9
  // inliers, 5.5 % with 10-14, 3.4 % with 15-19, 0.9 % with 20-29, 0.5 % with 30-49, 0.08 % with 50-79 and 0.2 % with
  // 80 or more, close to 8 / n² for n inliers. So a pose on n inliers is an outlier with probability
  // pose_outlier_probability · (pose_outlier_inliers / n)², within [pose_outlier_min, pose_outlier_max]
  // (PoseOutlierProbability; pose_outlier_inliers 0: pose_outlier_probability for every pose, as before). A start
  // whose pose on 113-127 features placed the camera an arc behind the key-image it verified best was not confident
  // with 0.02 (0.66-0.93: the pose wrong and the camera at the key-image weighed 7-34 %; three of the 1000 starts of
  // `scripts/kidnap-validation`). The upper bound stays the flat 0.02: raised to 0.2, the poses on fewer than 20
  // inliers (beside the path, kitti07 at 320 px) gave way to the other placements in frames they had right — over the
  // matrix 97.61 -> 97.46 % correct, 91.27 -> 90.81 % at 2.5 m, 13 frames on a wrong arc either way (docs/repeat.md,
  // "A pose on many inliers is rarely wrong").
  double pose_outlier_probability = 0.02;
  double pose_outlier_inliers = 20.0;
  double pose_outlier_min = 0.002;
  double pose_outlier_max = 0.02;
  // The tracked positions also share an error that does not average out over the features (the pose's covariance
  // assumes independent errors): aligned against references cut from key-images taken elsewhere, they are biased
  // together. A shared relative scale error δs of the image moves the pose along its viewing direction by δs times
  // the depth of its points (a facade 30 arc lengths ahead: 1 % of scale is 0.3 arc lengths; placement_test). δs has
  // σ = this many pixels over the inliers' RMS distance from the optical axis (PoseSpread): the tracked features' error
  // against the truth's projections, 0.17-0.24 px on seeds 1-3 (README, "Why those poses lag"). Over the validation
  // matrix the pose's error relative to its points' median depth had a 95th percentile of 1.2 % on the seven tuning
  // drives at 320x240 and 0.2 % on kitti07 (about 4 times the pixels per radian); without this term 22.6 % of the
  // placements resting on points 20-40 arc lengths away were more than 4 σ off.
  double pose_shared_error_px = 0.2;
  // A current geometry W_t:a / W_t:b through the decomposed transfer: its scale and translation direction come
  // from fewer, often distant features. Its placement error: median 0.010, 90th percentile 0.10 (σ = 0.06), above
  // 0.15 in 7.0-7.7 % of the frames (same measurement).
  double geometry_sigma = 0.06;
  double geometry_outlier_probability = 0.08;
  // ... within one arc length of the key-image the geometry relates the camera to. Beyond it (the camera placed past
  // the arc's other key-image, or behind the key-image), the transfer's scale comes from features shared with an arc
  // the camera has left, and the placement is mostly wrong: measured over the validation matrix (62 drives, 43 000
  // placements against the truth projected on the arc), the fraction more than 0.15 arc lengths off is 4-7 % up to
  // one arc length from the key-image, 25-67 % at 1-1.25, 72-92 % at 1.25-1.75 and 89-96 % beyond (median errors
  // 0.03-0.3, 0.6-0.7, 1.2-3.0 arc lengths). So at a distance d > 1 the outlier probability rises as
  // 1 − (1 − ε) exp(−(d − 1) / λ) with λ this many arc lengths (by this factor alone 0.44 at d = 1.125, 0.79 at 1.375,
  // 0.97 at 1.875; on the path the distance factor below adds to it).
  double geometry_extrapolation_length = 0.25;
  // ... and with the camera's distance d from that key-image in any direction, beside the path as well as along it:
  // of the placements within one arc length along the arc (validation matrix, 36 700 placements, docs/repeat.md "A
  // current geometry far beside its key-image"), 4.1 % were more than 0.15 arc lengths off with d ≤ 1, 14 % at
  // d = 1-1.25, 39 % at 1.25-1.5, 75 % at 1.5-2 and 81 % beyond. So the probability that it is right is multiplied by
  // exp(−(d − 1) / λ_d) beyond d = 1 too, λ_d this many arc lengths (maximum likelihood on those placements: 0.85).
  // A start 3 m beside arcs 3 m long took a W_t:a 3.4 arc lengths from its key-image as a good placement and reported
  // its first frame two arcs ahead. 0: off (the distance along the arc alone).
  double geometry_distance_length = 0.8;
  // A key-image verified by wide-baseline matching (bootstrap, relocalization): the camera is near it, on the
  // side the sign test of eq. (9) says, within about half an arc; look-alike places verify too (when wrong, the
  // pick is any of the candidates: the outlier range is their number of arc lengths).
  double key_image_sigma = 0.5;
  double key_image_outlier_probability = 0.2;
  // ... beside the taught path the verified key-image lies farther along it from the camera: over the 904
  // relocalizations of the validation matrix's simulated drives (README, "A key-image verified beside the path"),
  // the camera's distance along the path from the key-image it verified had an RMS of 0.37-0.38 arc lengths with the
  // camera less than 0.35 arc lengths beside the path, 0.69 at 0.35-0.5, 0.91 at 0.5-0.7 and 1.35 at 0.7-1 (mostly
  // behind it: from beside the path a key-image ahead matches the frame best). So for a camera l arc lengths beside
  // the path (by this frame's pose or the lane's last one, the larger) σ = hypot(key_image_sigma, this × l): 0.57 at
  // l = 0.2, 0.99 at 0.6, 1.29 at 0.85. 0: not used.
  double key_image_beside_sigma = 1.4;
  // A camera resected from the key-images a bootstrap verified (ResectFromKeyImages, VerifiedPoseMeasurement): its σ
  // along the arc is the pose's (as PoseMeasurement's) times `verified_pose_sigma_factor`, combined in quadrature with
  // `verified_pose_sigma_floor` arc lengths, with `verified_pose_outlier_probability`. Its points are triangulated from
  // ORB key-points (a pixel or so, matched 2.5 m beside the path and under another sun, not the tracker's sub-pixel
  // alignments) along the path, so the pose's covariance, from its own residuals, understates its error. Measured as
  // scripts/verified-placement-accuracy does (README, "Placed by the key-images a relocalization verified"), with a
  // first build that placed the camera in every bootstrap and gave it the pose's own σ: of 150 placements on the
  // twelve 2.5 m drives that the truth could judge, the error along the arc had a median of 0.12 and a 90th percentile
  // of 0.46 arc lengths, 2.2 and 7.9 times that σ; × 3 with the floor, 0.59 and 2.2 σ (a Gaussian: 0.67 and 1.64 —
  // the tail is the outlier probability's). With these defaults, the script on the fourteen drives 2.5-3 m beside:
  // 44 judged, median 0.074 and 90th percentile 0.30 arc lengths, 0.46 and 1.66 σ.
  double verified_pose_sigma_factor = 3.0;
  double verified_pose_sigma_floor = 0.1;
  double verified_pose_outlier_probability = 0.2;
  // The camera rides at the key-images' height: a camera fixed on a vehicle stays at its mounting height above the
  // road, so its centre lies on the line through the arc's two key-image centres, up to where the road leaves that
  // line, the vehicle's pitch and roll, and the ground normal's error times the lateral offset (PoseDeviation below).
  // An absolute pose whose centre lies off that line by more than these allow was fitted to features located in
  // the wrong places (features found on a repeated texture one period off, say, fit a camera hovering above the
  // road): its outlier probability is raised by Bayes' rule with the height deviation δ as the observation —
  //     ε' = max(ε, ε u / (ε u + (1 − ε) N(δ; 0, σ_δ² + σ_h²))),
  // σ_δ from the pose's covariance, σ_h this many arc lengths, u the density of δ for a wrong pose (uniform over
  // `pose_height_outlier_span` arc lengths). Raised only: a pose can also be wrong along the road at the right
  // height (a pose lagging half an arc 2-3 m beside the path, README), which a height on the line does not refute.
  // Measured on the default drive 2.5 m aside (repeat_sim_test, the normal fitted to the road): poses on the correct
  // arc lay 0.00-0.34 arc lengths off the line (σ_δ 0.01-0.16), one of 6 inliers 2.3 arcs ahead of the truth
  // 0.65-0.68 above it (σ_δ 0.15). The normal is the arc's (GroundNormalOfArc). 0 turns the check off.
  double pose_height_sigma = 0.05;
  double pose_height_outlier_span = 2.0;
  // The camera keeps to its lane: a vehicle's lateral offset from the taught path changes by the sine of its heading
  // against the path per length travelled, so the offsets of the recent poses predict this pose's. Measured over the
  // validation matrix (17 273 poses of its simulated drives against the truth, placed between the same bisecting
  // planes; README "The camera keeps to its lane"): the poses more than 0.15 arc lengths off along the arc lay 0.8 m
  // (median) beside the true offset, nearer the taught path — fitted to features aligned against references cut in
  // the key-images, they collapse towards what the key-images saw — while the poses right along the arc lay 0.03 m
  // (median; 95th percentile 0.29 m) from it. A collapse does not always take the position along the arc with it:
  // of the 257 poses (1.5 %) more than 0.6 m nearer the path than the recent poses, 38 % were more than 0.15 arc
  // lengths off along the arc (1.0 % of the others), with a median error of 0.107 and a 95th percentile of 0.433 arc
  // lengths (4.3 % beyond 0.5) — a wider Gaussian (σ 0.16 from the median, 0.22 from the 95th percentile), not a
  // uniform outlier: treating them as outliers put correct frames of the 1 m drives `lost`. So a pose's σ along the
  // arc grows to √(σ² + π σ_c²), π the posterior probability that it collapsed: a collapsed pose (prior
  // `pose_collapse_probability`) lies anywhere no farther from the path than the lane (uniform over the offsets
  // within the prediction's distance from the path, on either side — they overshoot it a little — widened by two
  // standard deviations), a pose on the lane is Gaussian around the prediction. A pose farther out than the lane is
  // not doubted (the lane itself may rest on collapsed poses: seed3's first two), nor is any on the path, where
  // nothing collapses. A pose across the path beyond the check's noise is another matter: a wrong pose, an outlier
  // (FarSideProbability). The prediction combines the poses of the last `lane_window` arc lengths of travel
  // (LanePrediction), each carried along its own heading against the path (a car steering back onto it from 1.5 m
  // beside turns by 8°: the offsets of a lane carried straight lagged it, and the poses that followed it looked
  // collapsed) with a standard deviation of `lane_heading_sigma` times the length travelled for the heading's change
  // (radians: 0.1 is 6°); a pose's own lateral error beyond its covariance has σ =
  // `pose_lateral_sigma` arc lengths (0.29 m on arcs of about 2.4 m is 2 σ). 0 turns the check off.
  double pose_lateral_sigma = 0.06;
  double lane_heading_sigma = 0.1;
  double lane_window = 3.0;
  double pose_collapse_probability = 0.015;
  double collapsed_pose_sigma = 0.2;  // σ_c, arc lengths
  // The lane's robust combination (LanePrediction): a recent pose's offset is wrong with this probability (a pose's
  // placement error, `pose_outlier_probability`'s measurement) and then uniform over this many arc lengths (the
  // span of the height check, `pose_height_outlier_span`: a wrong pose lies anywhere within about an arc of the path).
  double lane_outlier_probability = 0.02;
  double lane_outlier_span = 2.0;
  // The lane keeps at most this many recent poses, and one more than this many arcs of travel away no longer counts
  // (both bound its cost; `lane_window` arc lengths of travel are what it combines).
  int lane_max_poses = 16;
  int lane_max_arcs = 8;

  bool Check(std::string* error = nullptr) const;
};

// Where an absolute pose's inliers lie: their median depth in the current camera (arc lengths) and their RMS angle
// from its optical axis times the focal length (pixels). Zero depth: unknown.
struct PoseSpread {
  double median_depth = 0.0;
  double rms_radius_px = 0.0;
};
// The spread of the inliers of `pose`, estimated from `points_in_world` (the arc's reconstruction, whose key-images
// are `arc_length` apart) and `bearings`.
PoseSpread SpreadOfInliers(const AbsolutePose& pose, const std::vector<Vector3d>& points_in_world,
                           const std::vector<Vector3d>& bearings, double arc_length, double focal_length_px);

// A camera centre's deviation from where a vehicle's camera rides (arc lengths), with its standard deviation.
struct PoseDeviation {
  bool valid = false;
  double deviation = 0.0;
  double sigma = 0.0;
};
// How far the camera centre lies from the line through the arc's key-image centres, along the ground's normal
// (arc lengths; positive below the line, with a normal pointing down), and its standard deviation from the pose's
// covariance. Invalid without a ground normal or a covariance.
// `ground_normal`: the ground's unit normal in key-image a's frame; without it, the arc's own (GroundNormalOfArc).
PoseDeviation HeightOffArc(const AbsolutePose& pose, const Rigid3d& arc_b_from_a, const Vector3d& ground_normal);
PoseDeviation HeightOffArc(const AbsolutePose& pose, const Rigid3d& arc_b_from_a);
// How far the camera centre lies beside the line through the arc's key-image centres, perpendicular to it and to
// the ground's normal (arc lengths; positive to the right of the direction of travel), and its standard deviation
// from the pose's covariance. The normal is the arc's (GroundNormalOfArc). Invalid without a covariance.
PoseDeviation LateralOffArc(const AbsolutePose& pose, const Rigid3d& arc_b_from_a);

// A pose's lateral offset (LateralOffArc) and the lane's prediction of it (LanePrediction), arc lengths, with the
// standard deviation of their difference.
struct LaneCheck {
  bool valid = false;
  double lateral = 0.0;
  double predicted = 0.0;
  double sigma = 0.0;
};

// The posterior probability that a pose collapsed towards the taught path, from its lateral offset against the
// lane's prediction (PlacementModel::pose_lateral_sigma); 0 when `lane` is invalid or the check off.
double CollapseProbability(const LaneCheck& lane, const PlacementModel& model);

// The posterior probability that a pose on the far side of the taught path from the lane's prediction is a wrong pose:
// Bayes' rule over three explanations of its lateral offset l (arc lengths), σ² the lane check's variance
// (LaneCheck::sigma² + PlacementModel::pose_lateral_sigma²) — on the lane, N(l; p, σ²) around the prediction p
// (prior 1 − c within the right poses, c = PlacementModel::pose_collapse_probability); collapsed onto the path,
// N(l; 0, σ²) (prior c); or a wrong pose (prior PlacementModel::pose_outlier_probability, uniform over
// `lane_outlier_span` arc lengths). A collapse brings a pose onto the path, not across it: over the groups offset,
// beside, hard and mixed of the validation matrix (`scripts/validation offset beside hard mixed`, a temporary debug
// line with each pose's lateral offset; the poses with the truth 1 m or more aside), 32 of the 35 poses more than 0.1
// arc lengths on the other side of the path than the truth were more than 0.15 arc lengths off along the arc; of the
// 169 within 0.1 of the path 15 were, of the 6080 on the right side 226. With the lane 0.8 to the right and its σ 0.05:
// 0.12 at 0.01 to the left, 0.45 at 0.15, 0.78 at 0.2, 0.995 at 0.3. 0 on the lane's side of the path, and farther out
// on the other side than the lane is on its own by more than 2 σ (the lane may rest on poses that drifted across the
// path: `scripts/validation --random 24`'s rand1103 frames 470-476 took it to 0.17 to the left, and a first build
// without this exception refused the next 17 frames' poses, 0.56 to the right and right along the arc); 0 when `lane`
// is invalid or the check off.
double FarSideProbability(const LaneCheck& lane, const PlacementModel& model);

// The camera's heading against the taught path at `along` on the arc (radians, positive turned to the right about
// the ground's normal, GroundNormalOfArc): its yaw relative to key-image a less the path's, which turns from a's
// heading to b's along the arc. A camera fixed on a vehicle turns with it, so this is the vehicle's heading against
// the taught vehicle's whatever the mount's yaw; the lateral offset then changes by sin(heading) per length
// travelled. 0 when the camera looks along the ground's normal.
double HeadingOffArc(const Rigid3d& current_from_a, const Rigid3d& arc_b_from_a, double along);

// One recent pose's lateral offset (LateralOffArc times the arc's length: the belief's common unit) and the length
// travelled since (common units).
struct LaneObservation {
  double lateral = 0.0;
  double sigma = 0.0;
  double travelled = 0.0;
  double heading = 0.0;  // HeadingOffArc of the pose: the offset moves by sin(heading) per length travelled
};
// The lateral offset the recent poses predict here (common units), with its standard deviation: each observation
// carried along its own heading (lateral + sin(heading) · travelled), with a drift of `lane_heading_sigma` per
// length travelled for the heading's change, combined robustly (wrong poses come in runs:
// util/robust_random_walk.h, outliers with `lane_outlier_probability`, uniform over `lane_outlier_span` times
// `arc_length`). Invalid with fewer than two observations judged right (one recent pose may be the wrong one).
PoseDeviation LanePrediction(const std::vector<LaneObservation>& observations, double arc_length,
                             const PlacementModel& model);

// The ground's normal (pointing down) in key-image a's frame, from the arc alone: perpendicular to the arc's
// direction of travel and to the camera's x axis. A camera fixed on a vehicle travels along the road, so the
// direction of travel lies in the ground plane whatever the camera's pitch, the road's slope or a turn; its x axis
// does when the camera is mounted without roll, which is assumed — 2° of roll 2.5 m beside the path put the centre
// 9 cm off. No images are needed (the ground-plane fits of TaughtPath, which do not assume it, cost about 0.15 s for
// a map of the simulated town: a kidnapped start's first frame took 161 instead of 15 ms).
Vector3d GroundNormalOfArc(const Rigid3d& arc_b_from_a);

// The probability that an absolute pose on `inliers` inliers is an outlier (PlacementModel::pose_outlier_inliers).
double PoseOutlierProbability(int inliers, const PlacementModel& model);

// The measurements of the belief from one placement on `arc`. A pose's σ: its covariance (AlongSigma), the floor,
// and the shared scale error of its points' `spread` (PlacementModel::pose_shared_error_px) when known.
// Its outlier probability: PoseOutlierProbability of its inliers, raised by the centre's `height` off the arc
// when valid (PlacementModel::pose_height_sigma). Its σ grows with `collapse_probability`, the probability that it
// collapsed towards the path (CollapseProbability; PlacementModel::collapsed_pose_sigma); its outlier probability is
// at least `far_side_probability` (FarSideProbability).
PlaceMeasurement PoseMeasurement(arc_t arc, const ArcPosition& position, const AbsolutePose& pose,
                                 const Rigid3d& arc_b_from_a, const PlacementModel& model,
                                 const ArcBounds& bounds = ArcBounds(), const PoseSpread& spread = PoseSpread(),
                                 const PoseDeviation& height = PoseDeviation(), double collapse_probability = 0.0,
                                 double far_side_probability = 0.0);
// A camera resected from the key-images a bootstrap verified (ResectFromKeyImages): PoseMeasurement with the σ and
// outlier probability of PlacementModel's verified_pose_* (the height check as there).
PlaceMeasurement VerifiedPoseMeasurement(arc_t arc, const ArcPosition& position, const AbsolutePose& pose,
                                         const Rigid3d& arc_b_from_a, const PlacementModel& model,
                                         const ArcBounds& bounds = ArcBounds());
// `key`: the key-image of `arc` the current geometry relates the camera to (W_t:a: kA, W_t:b: kB). The outlier
// probability rises with the camera's distance from it along the arc and in any direction (`position`'s
// distance_to_from / distance_to_to; geometry_extrapolation_length, geometry_distance_length).
PlaceMeasurement GeometryMeasurement(arc_t arc, const ArcPosition& position, ArcImage key, const PlacementModel& model);
// The camera is at key-image `node` of `arc` (its start or its end), picked among `candidates` key-images; `beside`:
// the camera's distance from the taught path, arc lengths, when known (PlacementModel::key_image_beside_sigma).
PlaceMeasurement KeyImageMeasurement(const MapArc& arc, node_t node, int candidates, const PlacementModel& model,
                                     double beside = 0.0);

}  // namespace retrace
