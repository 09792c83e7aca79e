#pragma once

// Repeat: streaming localization in a taught map and steering (Segvic 2009 §3.3, §3.4, §5.2, §6.3; design §6).
//
// The Localizer is fed one frame at a time (ProcessFrame), as from a live camera, and keeps:
//  - a topological location: the current arc (I_i, I_i+1) of the map (called (a, b) below, a = arc.from,
//    b = arc.to), with its previous arc (ending at a) and its next arc (starting at b);
//  - the mapped features of these three arcs that are tracked now, each aligned by the reference-aligned tracker
//    to a reference appearance cut from a key-image (key-images are stored in the map).
//
// Per frame (state kTracking):
//  1. all tracked features are aligned to their references (the same pyramid settings as teach,
//     TrackingPyramidOptions, so the residual threshold R means the same in both phases);
//  2. the current geometries W_t:a and W_t:b are estimated from the tracked features whose positions in the
//     key-images a and b are known (robust 5-point, with σ_p, Segvic 2009 eq. (6); the previous frame's geometry,
//     or one derived from the previous frame's absolute pose, is the first hypothesis); a geometry is "usable" when
//     it succeeded with σ_p below `max_sigma_p_px`;
//  3. the camera is placed on the arc (FuseArcPositions): by its absolute pose in the arc's reconstruction (P3P on
//     the tracked features whose points Q the arc stores, σ_p gated like the current geometries), and by W_t:a and
//     W_t:b brought into the arc's frame and scale (decomposed point transfer, §4.4). The absolute pose is far more
//     accurate (README); a placement is believed only when it is continuous with the last accepted position and the
//     camera's speed along the arc (median of its last three steps): within `progress_tolerance` of where they put
//     the camera, `max_progress_step` while the speed is not known yet;
//  4. decomposed point transfer (§4.4): the current arc's points are predicted through the more accurate usable one
//     of W_t:a / W_t:b whose placement agrees with the believed position, the next arc's through W_t:b, the previous
//     arc's through W_t:a — only through usable geometries (σ_p gating, §5.2.1);
//  5. consistency: a tracked feature farther than `max_drift_px` (or 3 σ_p) from its prediction is discontinued —
//     after a sanity check of the transfer itself: when more than `max_drift_fraction` of an arc's tracks disagree
//     with it, the transfer is distrusted for that frame (no drops, no predictions for that arc);
//  6. prudence (eqs. (7), (8)): features of the next arc are resumed only when the camera is closer to b than
//     `next_arc_ratio` (0.5) of the arc length, those of the previous arc only when closer to a than
//     `previous_arc_ratio` (0.3);
//  7. resumption: every mapped but untracked feature predicted inside the image is refined against its
//     reference (RefinePrediction, starting at scale = 1 / distance ratio) and accepted only near the
//     prediction; a rejected feature is retried after `retry_interval` frames. References are cut from the arc's
//     key-image nearest to the camera. A neighbouring arc that shares too few features with the current geometry
//     is reached through the relative scale stored at the common node; when the map stores none (kitti07 has such
//     nodes in its turns) or right after a transition, the features seen in the nearby key-image are predicted by
//     the rotation between that key-image and the current image (Kabsch on the tracked features seen in both),
//     aligned, and accepted only when they agree with the median offset of all candidates;
//  8. topological transition (eq. (9)): forward when the camera centre passes the plane through b's centre
//     perpendicular to the arc's direction of travel, i.e. when the believed position along the arc exceeds 1;
//     backward when it lies more than `backward_margin` behind a. It needs the absolute pose or both current
//     geometries agreeing, so it is cancelled when no estimate with an acceptable σ_p places the camera. Position
//     and speed carry over into the next arc through the relative scale stored at the node, and a camera past the
//     new arc's end too makes a second transition (short arcs: kitti07 at 320 px passes about one arc per frame in
//     its turns). After a transition the features of the arc two behind are dropped and the references are
//     redefined (§5.2.2): the new current arc's features are re-aligned against the key-image now approached, the
//     previous arc's against the key-image just passed; a feature whose new reference does not align at its
//     current position keeps the old one (re-cutting blindly lost most tracks in kitti07's turns);
//  9. steering (eq. (10)): w = k * mean(x_t - x*) over the current arc's features, x the horizontal normalised
//     coordinate in the current image and x* in key-image b.
//
// Lost is an answer: when fewer than `min_features` of the current arc are tracked, neither current geometry is
// usable or no placement is continuous for `max_bad_frames` frames in a row, the tracker is cleared and the same
// frame is re-initialised by wide-baseline matching against the key-images, exactly as the bootstrap; when that
// fails the frame is kLost (no arc is reported) and the following frames keep trying (kRelocalizing). A frame
// without any believed placement that the camera's speed puts more than `stale_margin` past the arc's end is
// reported kLost too (its tracks are kept): the arc is then most likely one the camera has left.
//
// Bootstrap (§3.3): the frame is matched (SIFT, ratio 0.8) against the key-images of a given start arc, or —
// without one — against every key-image (retrieval); after a loss only the key-images within
// `relocalization_neighbourhood` arcs of where it was lost, widened by `relocalization_widening` arcs per frame
// since, and the whole map only after `global_relocalization_frames` (look-alike streets elsewhere verify too).
// Candidates are ranked by whole-image appearance (GlobalDescriptor) and the `retrieval_shortlist` most alike are
// verified geometrically (relative pose on the matches); the rest too unless one of them has
// `retrieval_confident_inliers`. The key-image with most inliers wins. Its arc is chosen by which side of the
// key-image the camera is on (the sign test of eq. (9), which needs no scale), and corrected in the same frame by a
// transition when the absolute pose places the camera beyond the arc. The mapped features of that arc and of its two
// neighbours seen in the matched key-images are then located in the frame from the displacement of the nearest
// matched key-points and refined against their references (without the coarsest pyramid level, like every refined
// prediction); the regular transfer predicts the remaining ones from the next frame on. Key-images of these three
// arcs that retrieval did not verify are verified for this.

#include <array>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "retrace/camera/camera_model.h"
#include "retrace/dataset/sequence.h"
#include "retrace/feature/feature_tracker.h"
#include "retrace/feature/global_descriptor.h"
#include "retrace/feature/image_pyramid.h"
#include "retrace/feature/wide_baseline.h"
#include "retrace/geometry/absolute_pose.h"
#include "retrace/geometry/point_transfer.h"
#include "retrace/geometry/two_view_geometry.h"
#include "retrace/map/map.h"

namespace retrace {

enum class LocalizerState { kTracking, kLost, kRelocalizing };
const char* LocalizerStateName(LocalizerState state);

struct LocalizerOptions {
  // Pixel quantities below are given for images of this width and scaled by (image width / reference_width),
  // as in teach.
  int reference_width = 320;
  // Gaussian pre-smoothing of the tracker's images (pixels at reference_width); must equal teach's (the map
  // stores teach's value, `retrace repeat` takes it from there).
  double smoothing_sigma_px = kTrackingSmoothingPx;
  // R: largest RMS residual of a track against its reference (grey levels). Segvic 2009: 6.
  double max_residual = 6.0;
  // σ_p gate (px at reference_width): predictions, consistency checks and transitions use a current geometry only
  // when its σ_p is below this. Teach's r_p (4 px) by default.
  double max_sigma_p_px = 4.0;
  // Sampson-error threshold of the current geometries' inliers (px at reference_width); teach uses the same.
  double inlier_threshold_px = 1.5;
  // A current geometry needs this median parallax of its inliers (px at reference_width), as in teach. Mapped
  // features are often distant (they are the ones that stay visible over an arc), so a stricter guard fails many
  // current geometries in mid-arc: 2 px at 320x240 failed 110 of 480 in the simulated town.
  double min_parallax_px = 0.5;
  // Segvic 2009, eq. (7): resume the next arc's features when (distance to b) / (arc length) < this.
  double next_arc_ratio = 0.5;
  // Segvic 2009, eq. (8): resume the previous arc's features when (distance to a) / (arc length) < this.
  double previous_arc_ratio = 0.3;
  // A refined prediction is accepted within this distance of the prediction (px at reference_width).
  double prediction_radius_px = 2.0;
  // Predictions (point transfer, bootstrap) are refined on the tracking pyramid without this many of its coarsest
  // levels: they are already within a few pixels, and the coarsest windows (60 px wide at 320 px) slide onto
  // other structures — in the simulated town most bootstrap refinements ended 20-40 px from a good prediction.
  int prediction_skipped_levels = 1;
  // ... and with converged scale / initial scale within [1 / ratio, ratio].
  double prediction_scale_ratio = 1.25;
  // Consistency: a tracked feature farther than max(this, 3 σ_p) from its prediction is discontinued (px at
  // reference_width).
  double max_drift_px = 3.0;
  // Sanity check of a transfer: when more than this fraction of an arc's tracked features (and more than 3) drift
  // from their predictions, the transfer is distrusted for that frame instead of the tracks.
  double max_drift_fraction = 0.25;
  // A frame without any believed placement is reported lost (the tracks are kept) when the last position and the
  // camera's speed put it more than this (arc lengths) past the arc's end: the arc is then most likely stale (in the
  // simulated town, three such frames stayed on an arc the camera had left two arcs before).
  double stale_margin = 0.5;
  // Backward transitions need the camera this far (arc lengths) behind a: hysteresis against flicker right after
  // a forward transition, where W_t:a has almost no baseline.
  double backward_margin = 0.1;
  // Two current geometries whose placements of the camera on the arc differ by at most this (arc lengths) are
  // averaged (FuseArcPositions).
  double position_agreement = 0.1;
  // When the absolute pose placed the camera, a current geometry's transfer predicts the current arc's features only
  // when its own placement lies within this (arc lengths) of the absolute pose's.
  double transfer_agreement = 0.25;
  // Continuity of the position along the arc (PositionContinuous): a placement farther than this (arc lengths)
  // from where the last accepted position puts the camera is not believed while the camera's speed along the arc
  // is unknown (first frames on an arc) ...
  double max_progress_step = 0.75;
  // ... and farther than this from where the last position and the speed put it once the speed is known (at least
  // one frame of motion either way). 0.75 let a pose from 10 distant features right after a transition place the
  // camera past the next node (simulated town: three transitions in three frames, two arcs ahead of the truth).
  double progress_tolerance = 0.3;
  // Segvic 2009 §5.2.2: after a transition, redefine the references of the new current arc's features from the
  // key-image approached and of the arc just left from the key-image passed (a feature whose new reference does not
  // align at its current position keeps the old one).
  bool redefine_references = true;
  // Frames before a rejected prediction of a feature is tried again. 1: in the next frame. At 8 m/s in the
  // simulated town an arc lasts 3-5 frames, and waiting 3 frames let the next arc's features be predicted only once
  // before the camera reached it (14 drives: lowest 98.0 % correct with 3, 99.0 % with 1; the simulated repeat
  // benchmark 482 -> 372 frames/s).
  int retry_interval = 1;
  // Fewest tracked features of the current arc for a good frame. The current geometries and σ_p decide whether
  // the features are trustworthy; at 320x240 an arc maps ~50 features, and 15 made the simulated drive lost in
  // mid-arc (80.0 % vs 77.3 % correct with 10, no frame two arcs off either way).
  int min_features = 10;
  // Bad frames in a row (too few features or no usable current geometry) after which the state is lost.
  int max_bad_frames = 3;
  // k of Segvic 2009, eq. (10), radians of steering per unit of normalised image coordinate.
  double steering_gain = 1.0;
  // Bootstrap / relocalization: fewest geometrically verified wide-baseline matches with the best key-image.
  int min_bootstrap_inliers = 30;
  // ... and fewest mapped features located in the frame for the bootstrap to succeed (enough for the current
  // geometries; the arc itself is already decided by the verified key-image). Under another sun many mapped
  // features (tree canopies, shadowed facades) no longer align within R: in the simulated town's crossings the
  // bootstrap located 8-19 of them for 15 frames in a row, and 20 kept the drive relocalizing there (demo drive
  // 92.7 % correct with 12, 94.3 % with 8; kitti07 100 % either way).
  int min_bootstrap_features = 8;
  // Relocalization after a loss matches the key-images of the arcs up to this many arcs around the arc where it
  // was lost, ...
  int relocalization_neighbourhood = 3;
  // ... plus this many arcs more for every frame since the loss (kitti07 at 320 px passes about one arc per frame
  // in its turns), ...
  int relocalization_widening = 1;
  // ... and every key-image of the map once it has been lost for this many frames (a robot carried elsewhere).
  int global_relocalization_frames = 20;
  // Retrieval: the candidate key-images (the whole map, or the window around a loss) are ranked by whole-image
  // appearance (GlobalDescriptor) and the most similar `retrieval_shortlist` are verified by wide-baseline matching
  // first; 0 verifies every candidate. Extracting a key-image's key-points costs 187 ms at 1226x370, so this
  // decides how long the first frame takes (kitti07's 18 key-images: 4.3 s when all are verified, BM_FindStartKitti/0).
  int retrieval_shortlist = 5;
  // ... the other candidates are verified as well unless the best verified key-image has at least this many inliers
  // (a look-alike street elsewhere in the simulated town verified with 42; the right key-image has hundreds on
  // kitti07 and 60-150 in the simulated town).
  int retrieval_confident_inliers = 60;
  GlobalDescriptorOptions retrieval;
  // Bootstrap: matched key-points nearer than this (px at reference_width) predict a mapped feature's position.
  double bootstrap_neighbour_radius_px = 30.0;
  // Bootstrap: accept a located feature within this distance of its local prediction (px at reference_width).
  double bootstrap_radius_px = 4.0;

  // Place the camera on the arc by its absolute pose in the arc's reconstruction (FuseArcPositions) when that pose
  // is available; false: by the current geometries alone, as the paper (measured on the simulated town in the
  // README).
  bool place_by_absolute_pose = true;
  // The absolute pose: P3P samples, MSAC with the inlier threshold `inlier_threshold_px` (set by the Localizer).
  AbsolutePoseOptions pose;

  FeatureTrackerOptions tracker;
  // The current geometries W_t:a, W_t:b are estimated every frame from tracked features (inlier ratios ~90 %), so
  // the adaptive sampler's floor is lowered from 100 to 30 samples (at 90 % inliers the adaptive bound is ~12).
  TwoViewOptions geometry = CurrentGeometryOptions();
  // Wide-baseline matching for the bootstrap and relocalization. The ratio is looser than the paper's 0.6 (§4.1),
  // as in teach's gap recovery: every match must also agree with a robustly estimated relative pose, and under
  // another sun 0.6 kept 26 matches between two nearly identical 320x240 views of the simulated town (too few to
  // verify a key-image).
  WideBaselineOptions matching = [] {
    WideBaselineOptions o;
    o.ratio = 0.8;
    return o;
  }();

  static TwoViewOptions CurrentGeometryOptions() {
    TwoViewOptions options;
    options.ransac.min_iterations = 30;
    return options;
  }

  bool Check(std::string* error = nullptr) const;
};

// The role of an arc relative to the current topological location.
enum class ArcRole : int { kPrevious = 0, kCurrent = 1, kNext = 2 };

// A feature position drawn in overlays: tracked (square) or a rejected prediction (cross).
struct FeatureMark {
  Vector2d position = Vector2d::Zero();
  ArcRole role = ArcRole::kCurrent;
  bool tracked = true;
};

struct FrameResult {
  size_t frame_index = 0;  // Frame::index of the processed frame
  LocalizerState state = LocalizerState::kRelocalizing;
  // The current arc and its nodes; invalid (-1) unless state == kTracking.
  arc_t arc = kInvalidArcId;
  node_t node_from = kInvalidNodeId;
  node_t node_to = kInvalidNodeId;
  int tracked = 0;                        // features tracked after this frame (all arcs)
  std::array<int, 3> tracked_by_role{};  // ... per ArcRole (a feature of several arcs counts for the first role)
  int resumed = 0;                       // features (re)started by prediction or bootstrap in this frame
  int rejected = 0;                      // predictions refined but not accepted (drawn as crosses)
  int dropped = 0;                       // features lost by the tracker or discontinued by the consistency check
  int drifted = 0;                       // ... of which discontinued for drifting from their prediction
  int redefined = 0;                     // features whose reference was redefined at a transition
  double sigma_p_from = -1.0;            // σ_p of W_t:a, px; -1 when not estimated / failed
  double sigma_p_to = -1.0;              // σ_p of W_t:b
  double sigma_p = -1.0;                 // σ_p of the geometry used for the current arc's transfer
  double position_on_arc = 0.0;          // projection of the camera on the arc (0 at a, 1 at b), when known
  bool position_valid = false;
  // The same position through each estimate (W_t:a, W_t:b, the absolute pose in the arc's reconstruction); NaN when
  // that estimate gives none.
  double position_via_from = std::numeric_limits<double>::quiet_NaN();
  double position_via_to = std::numeric_limits<double>::quiet_NaN();
  double position_via_pose = std::numeric_limits<double>::quiet_NaN();
  double sigma_p_pose = -1.0;            // σ_p of the absolute pose in the arc's reconstruction
  int pose_inliers = 0;                  // its inliers (features of the current arc)
  // Segvic 2009 eq. (10), radians (0 when not valid). Image x grows to the right, so w < 0 turns left: towards
  // where the next key-image looks (checked against ground truth in repeat_sim_test). Simulator::Step takes
  // positive = left, i.e. -w.
  double steering = 0.0;
  bool steering_valid = false;
  int transition = 0;         // +1 forward, -1 backward, 0 none in this frame (+2: two arcs forward)
  bool bootstrapped = false;  // (re)initialised by wide-baseline matching in this frame
  int key_images_matched =
      0;  // key-images verified by wide-baseline matching in this frame (bootstrap, relocalization)
  double seconds = 0.0;       // processing time of this frame
  std::vector<FeatureMark> marks;  // tracked features and rejected predictions (for overlays)
};

// Where the current camera is relative to an arc, in the arc's frame and unit (|t| = 1).
struct ArcPosition {
  bool valid = false;
  double along = 0.0;             // (C_t - C_a) . (C_b - C_a): 0 at a, 1 at b
  double distance_to_from = 0.0;  // |C_t - C_a| (arc lengths)
  double distance_to_to = 0.0;    // |C_t - C_b|
};
// `current_from_a`: the current camera in the arc's frame and scale (PointTransfer::current_from_a()).
ArcPosition LocateOnArc(const Rigid3d& current_from_a, const Rigid3d& arc_b_from_a);

// Prudence (Segvic 2009, eqs. (7), (8)): which neighbouring arcs may have features resumed at `position`.
struct ResumptionPolicy {
  bool next = false;
  bool previous = false;
};
ResumptionPolicy DecideResumption(const ArcPosition& position, double next_arc_ratio = 0.5,
                                  double previous_arc_ratio = 0.3);

// A current geometry (σ_p gating, Segvic 2009 §5.2.1): usable when it succeeded with σ_p below `max_sigma_p_px`.
bool GeometryUsable(const TwoViewGeometry& geometry, double max_sigma_p_px);

// The last accepted position of the camera along the current arc and its speed.
struct ArcProgress {
  double along = 0.0;        // arc lengths (0 at a, 1 at b)
  double speed = 0.0;        // arc lengths per frame: median of the last steps, when speed_known
  size_t frame = 0;          // frame counter of the acceptance
  bool speed_known = false;
  std::array<double, 3> steps{};  // the last steps (arc lengths per frame), newest first
  int num_steps = 0;
};

// How far (arc lengths) a new position along the arc may lie from where the last accepted position and the
// camera's speed put it, and still be believed.
struct ContinuityLimits {
  double unknown_speed = 0.75;  // while the speed along the arc is not known
  double known_speed = 0.3;     // once it is
};

// Continuity of the position along an arc (arc lengths): a new position in frame `frame` is believed when no
// earlier one is known on this arc, or when it lies within max(limit, the distance covered in one frame at the
// last speed) of where the last accepted position and speed put the camera now.
bool PositionContinuous(const std::optional<ArcProgress>& last, size_t frame, double along,
                        const ContinuityLimits& limits);

// A placement of the current camera on the arc by one estimate, with that estimate's σ_p (px).
struct PlacedCamera {
  ArcPosition position;
  double sigma_p = 0.0;
};

// The camera's position along the current arc. Three estimates place it (only those whose σ_p passed the gate are
// given, Segvic 2009 §5.2.1):
//  - `via_pose`: the absolute pose of the current camera in the arc's reconstruction (the points Q of W_k that are
//    tracked now; geometry/absolute_pose.h);
//  - `via_from`, `via_to`: the current geometries W_t:a, W_t:b brought into the arc's frame and scale (the
//    decomposed point transfer, §4.4).
// The absolute pose needs no separate scale estimate and is far more accurate: in the simulated town (5 drives,
// other sun, 1 m offset) its placements were more than 0.15 arc lengths from the truth in 1-2 % of the frames,
// those of W_t:a / W_t:b in 6-15 % (a current geometry from few or distant features, whose translation direction
// or scale is poorly determined). A placement is believed only when it is continuous with the last accepted
// position (PositionContinuous). The absolute pose is taken when believed; otherwise, of the
// believed decomposed placements the nearest to where the camera's speed puts it is taken, averaged with the other
// when both agree within `agreement` arc lengths (without a last position the lower σ_p decides).
struct FusedArcPosition {
  ArcPosition position;     // invalid when no placement is believed
  bool continuous = true;   // false: placed, but no placement continuous with the last accepted position
  bool via_pose = false;    // the absolute pose's placement was used
  bool via_from = false;    // W_t:a's placement was used
  bool via_to = false;      // W_t:b's placement was used
};
FusedArcPosition FuseArcPositions(const std::optional<ArcProgress>& last, size_t frame,
                                  const std::optional<PlacedCamera>& via_pose,
                                  const std::optional<PlacedCamera>& via_from,
                                  const std::optional<PlacedCamera>& via_to, const ContinuityLimits& limits,
                                  double agreement);

// Topological transition (Segvic 2009 §5.2.2, eq. (9)): forward (+1) when the camera centre has passed the plane
// through b's centre perpendicular to the arc's direction of travel, i.e. its projection on the arc lies beyond b
// (along > 1); backward (-1) when it lies more than `backward_margin` arc lengths behind a; else 0. `position` is
// the fused position (FuseArcPositions), so a transition is cancelled when no estimate with an acceptable σ_p
// places the camera.
int DecideTransition(const ArcPosition& position, double backward_margin);

class Localizer {
 public:
  // `map` must hold its key-images (MapDatabase::ReadMap(true)); it is copied (images are shared, not
  // duplicated). `camera` describes the frames given to ProcessFrame.
  Localizer(const Map& map, const CameraModel& camera, const LocalizerOptions& options = {});
  ~Localizer();

  // Bootstrap the first frame against this arc's key-images only (Segvic 2009 §3.3: the user gives the start
  // arc). Without it, or after a loss, the localizer finds the arc itself by retrieval over all key-images.
  void SetStartArc(arc_t arc);

  // Processes the next frame (8-bit gray, camera-sized; throws InputError otherwise).
  FrameResult ProcessFrame(const Frame& frame);

  LocalizerState state() const { return state_; }
  arc_t current_arc() const { return arc_; }
  const LocalizerOptions& options() const { return options_; }
  // Thresholds in pixels of the frames given.
  double sigma_p_threshold_px() const { return max_sigma_p_px_; }

 private:
  struct NodeData;
  struct ArcData;
  struct CurrentGeometry;

  NodeData& Node(node_t id);
  const ArcData* Arc(arc_t id) const;
  const ImagePyramid& NodePyramid(node_t id);
  const WideBaselineFeatures& NodeWideBaseline(node_t id);
  // The reference appearance of `feature` cut from key-image `node` (cached), or null when it cannot be cut.
  const ReferencePatch* Reference(node_t node, feature_t feature);
  // The key-image of `arc` whose appearance serves as reference for `feature`: `preferred` (the arc's key-image
  // nearest to the camera) when the feature is seen there, else the other one; invalid when seen in neither.
  node_t ReferenceNode(const ArcData& arc, feature_t feature, node_t preferred) const;

  // A key-image verified against the current frame by wide-baseline matching and a relative pose.
  struct MatchedKeyImage {
    node_t node = kInvalidNodeId;
    TwoViewGeometry geometry;  // key-image = a, current frame = b
    std::vector<Vector2d> key_points, current_points;  // inlier matches
    std::vector<double> size_ratios;                   // key-point size in the frame / in the key-image
  };
  // Verifies `candidates` by wide-baseline matching, the most similar in appearance to `image` first (see
  // LocalizerOptions::retrieval_shortlist); every candidate tried is added to `tried`.
  std::vector<MatchedKeyImage> RetrieveKeyImages(const cv::Mat& image, const WideBaselineFeatures& current,
                                                 const std::vector<node_t>& candidates, std::vector<node_t>* tried);
  std::vector<MatchedKeyImage> MatchKeyImages(const WideBaselineFeatures& current,
                                              const std::vector<node_t>& candidates);
  // The key-images of the arcs up to `arcs` arcs before and after `arc`, nearest first.
  std::vector<node_t> NodesNear(arc_t arc, int arcs) const;
  bool Bootstrap(const Frame& frame, FrameResult* result);
  void Localize(FrameResult* result);
  CurrentGeometry EstimateCurrentGeometry(node_t node);
  // The first hypothesis for the current geometry towards `node`: the previous frame's, else one derived from the
  // previous frame's absolute pose; none when neither relates to `node`.
  std::optional<Rigid3d> GuessCurrentFrom(node_t node) const;
  // The absolute pose of the current camera in `arc`'s reconstruction, from the tracked features it reconstructs.
  AbsolutePose EstimatePoseInArc(const ArcData& arc) const;
  void ApplyTransition(int direction, FrameResult* result);
  // Re-aligns the tracked features of `arc` against references cut from key-image `node`; a feature that does not
  // align there keeps its old reference.
  void RedefineReferences(const ArcData& arc, node_t node, FrameResult* result);
  // Length conversion across the node between consecutive arcs (direction +1: `new_arc` follows `old_arc`): a
  // length in units of `old_arc` times this is the same length in units of `new_arc`; none without a stored scale.
  std::optional<double> UnitRatio(arc_t old_arc, arc_t new_arc, int direction) const;
  // Records the (fused, continuous) position along the current arc of this frame and updates the speed.
  void AcceptProgress(double along);
  // Resumes untracked features of `arc` seen in key-image `node`, predicted from the displacement (key-image ->
  // current image) of the tracked features seen there that lie nearby.
  void ResumeFromNeighbours(const ArcData& arc, node_t node, ArcRole role, FrameResult* result);
  // Resumes untracked features of `arc` seen in key-image `node`, predicted by the rotation current_from_node (far
  // points move with the rotation alone) and corrected by the median offset of the converged alignments.
  void ResumeByRotation(const ArcData& arc, node_t node, const Matrix3d& rotation, double scale, ArcRole role,
                        FrameResult* result);
  void ClearTracks();
  void FillCounts(FrameResult* result) const;

  std::unique_ptr<CameraModel> camera_;
  LocalizerOptions options_;
  Map map_;
  std::unordered_map<node_t, std::unique_ptr<NodeData>> nodes_;
  std::unordered_map<arc_t, std::unique_ptr<ArcData>> arcs_;

  double pixel_scale_ = 1.0;
  double max_sigma_p_px_ = 0.0;
  ImagePyramidOptions pyramid_options_;
  TwoViewOptions geometry_options_;
  AbsolutePoseOptions pose_options_;
  RefinePredictionOptions refine_options_;
  FeatureTracker tracker_;

  ImagePyramid pyramid_;
  ImagePyramid prediction_pyramid_;  // pyramid_ without its coarsest levels (refinement of predictions)
  size_t frame_counter_ = 0;
  LocalizerState state_ = LocalizerState::kRelocalizing;
  arc_t arc_ = kInvalidArcId;
  arc_t start_arc_ = kInvalidArcId;
  int bad_frames_ = 0;
  bool stale_ = false;  // this frame: no placement, and the speed puts the camera past the arc (reported lost)
  arc_t last_arc_ = kInvalidArcId;       // the arc where the localizer was last lost
  size_t lost_at_frame_ = 0;             // frame counter of that loss
  std::optional<ArcProgress> progress_;  // last accepted position along the current arc and its speed
  node_t last_passed_ = kInvalidNodeId;  // the key-image passed by the last transition
  // Key-image each tracked feature takes its reference from.
  std::unordered_map<feature_t, node_t> reference_node_;
  // Frame counter before which a rejected prediction is not retried.
  std::unordered_map<feature_t, size_t> retry_after_;
  // The last successful current geometry towards each key-image (the next frame's first hypothesis), and the last
  // absolute pose of the camera in an arc's reconstruction (the first hypothesis towards a key-image new to it).
  std::unordered_map<node_t, Rigid3d> last_geometry_;
  struct LastPose {
    arc_t arc = kInvalidArcId;
    Rigid3d current_from_from;  // in the arc's frame and unit
  };
  std::optional<LastPose> last_pose_;
  // Current bearings of the tracked features (this frame).
  std::unordered_map<feature_t, Vector3d> bearings_;
};

}  // namespace retrace
