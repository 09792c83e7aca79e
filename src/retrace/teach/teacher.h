#pragma once

// Teach: building the hybrid topological-geometric map from one drive (Segvic 2009 §5.1, design §5).
//
// Mapping by tracking. A subrange starts at a key-image K with every corner of K handed to the reference-aligned
// tracker. After each frame f the two-view geometry W(K, f) is estimated from the features tracked since K. When its
// σ_p exceeds r_p, or fewer than n features survive, the previous frame becomes the next key-image: the arc (K, f-1)
// keeps W(K, f-1) (R, unit t, the 3D points of its inliers, σ_p) and a new subrange starts at f-1. Key-images are
// therefore dense where the scene is hard and sparse on easy straight roads.
//
// Gap recovery. When tracking fails at once (a frame gap, a full occlusion) right after a key-image, the key-image
// and the current image are related by wide-baseline matching instead, so the graph stays connected.
//
// Mapping by matching. Every 30th frame is a candidate key-image; consecutive candidates are related by
// wide-baseline matching (matched_geometry.h), and where an arc has fewer than n trackable features or σ_p above
// r_p, the frame halfway between its key-images is inserted and both halves are tried again (recursively). This
// mode keeps the frames in memory until Finish().
//
// Loop closing. After the last frame, the last key-image is matched with the first ones (the first five: where
// the drive began, the last key-image may lie between two of them); the best geometrically verified candidate
// that the drive around it confirms gets an arc from the last key-image and the graph becomes circular.
//
// Links made by matching are verified beyond their pair of images (link_verification.h): a link A -> B is kept when
// the drive after B confirms it and no other neighbour contradicts it. A loop candidate L -> F needs L, matched with
// the key-image after F, to show the motion of the link followed by the tracked arc from F; F's and L's
// predecessors, matched with L and F, may fail to relate but must not disagree. A gap arc K -> G is held back until
// the next key-image H: K matched with the frames tracked from G on must show the gap arc followed by the tracked
// W(G, f); when tracking fails at once after G too (a slow camera, a fast car: at a low frame rate every arc may be
// a gap arc), G -> H is a gap arc itself and K matched with H must show the two gap arcs composed, three key-images
// whose pairwise geometries agree. A tracked frame whose W(G, f) reconstructs features of the gap arc also gives
// the ratio of the two lengths (design §3.3), and K matched with it must then show the one composed direction at that
// ratio, not merely one of those any ratio allows (link_verification.h). The last of these witnesses that relates to
// K decides; K's predecessor matched with G must not disagree. Until then, and for good when it is not confirmed (no
// witness relates, one disagrees, or the drive ends at G), the map is disconnected at G. Every rejected candidate is
// reported (TeachStatistics::rejected_links).
//
// Several drives in one map (Booij 2007 §B.2, design §7). A teacher given an existing map (AppendTo) numbers its
// nodes, arcs and features after the map's and marks its key-images with the next route number. After the drive
// (Finish) every key-image of it is linked to the existing graph where the two see the same place: the existing
// key-images closest in appearance (global descriptor, a shortlist of TeachOptions::join_candidates) are related by
// wide-baseline matching; a candidate needs a geometry as good as a loop closure's (min_loop_inliers within r_p,
// not explained by one plane), a similarity S_ij of at least min_join_similarity (Booij: 0.05), and the witnesses
// of link_verification.h: the key-images next to B on its route (after and before it), matched with A, must show the
// link followed by their arc, at least one confirming and none contradicting, and the key-image before A on the new
// drive, matched with B, must not contradict it. The best confirmed candidate of each key-image becomes an arc of
// kind "join" A -> B with the geometry of the matching (R, t, the 3D points of its trackable inliers, σ_p) and its
// similarity; rejected candidates are reported (TeachStatistics::rejected_links, kind "join").
//
// The relative scale between consecutive arcs is stored at their common node (median of depth ratios of the
// features reconstructed in both, design §3.3).
//
// Frames are processed one at a time as they arrive (AddFrame), so the same code can run on a live camera; every
// key-image is committed to the map database in its own transaction together with the arc that reaches it.

#include <array>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include <opencv2/core.hpp>

#include "retrace/camera/camera_model.h"
#include "retrace/dataset/sequence.h"
#include "retrace/feature/binary_features.h"
#include "retrace/feature/corner_detector.h"
#include "retrace/feature/feature_tracker.h"
#include "retrace/feature/global_descriptor.h"
#include "retrace/feature/image_pyramid.h"
#include "retrace/feature/wide_baseline.h"
#include "retrace/geometry/two_view_geometry.h"
#include "retrace/map/map.h"
#include "retrace/map/map_database.h"
#include "retrace/teach/matched_geometry.h"
#include "retrace/teach/planar_degeneracy.h"

namespace retrace {

struct TeachOptions {
  enum class Method {
    kTracking,  // Segvic 2009 §5.1 "mapping by tracking" (default)
    kMatching,  // "mapping by matching": every k-th frame, key-images inserted where an arc is too weak
  };
  Method method = Method::kTracking;
  // Mapping by matching: frames between the initial key-image candidates (Segvic 2009: 30).
  int matching_interval = 30;

  // Pixel thresholds below are given for images of this width (Segvic 2009 works at 320x240) and scaled by
  // (image width / reference_width).
  int reference_width = 320;
  // r_p: a new key-image when σ_p of W(K, f) exceeds this (pixels at reference_width). Segvic 2009 §5.1: 4 px.
  double max_sigma_p_px = 4.0;
  // n: a new key-image when fewer features survive since K. Segvic 2009 §5.1: 50.
  int min_features = 50;
  // ... or fewer than this fraction of the features tracked from K on (when that is more than n). The arc keeps the
  // features that survive it; a map repeated under other light needs enough of them: in the simulated town (570
  // corners per key-image at 320x240) n = 50 alone kept 55 per arc, of which too few align again under another
  // sun (see README). 0 = the paper's rule.
  double min_features_fraction = 0.2;
  // R: tracks whose RMS residual against their reference exceeds this are dropped (grey levels). Paper: 6.
  double max_residual = 6.0;
  // Corners handed to the tracker at the start of a subrange, surviving tracks included.
  int max_corners = 1000;
  // Minimum distance between corners (pixels at reference_width).
  double corner_min_distance_px = 2.0;
  // Gaussian pre-smoothing of the tracker's images (pixels at reference_width). Scaling it with the image keeps
  // the residual R meaningful at any resolution: fine texture that the paper's 320x240 images did not resolve
  // would otherwise count as appearance change.
  double smoothing_sigma_px = kTrackingSmoothingPx;
  // Sampson-error threshold of the geometry's inliers (pixels at reference_width).
  double inlier_threshold_px = 1.5;
  // A geometry needs this median parallax (pixels at reference_width) before it is trusted; below it the camera has
  // not moved enough yet and no key-image is needed.
  double min_parallax_px = 0.5;
  // What each key-image stores for relocalization (map.h KeyImageSignature; issue 16): binary key-points for the
  // verification by matching and the quantised appearance thumbnail for retrieval, computed once here instead of at
  // every repeat (about 4 ms per key-image at 320x240). false: none stored (repeat computes them when it loads the
  // map).
  bool store_signatures = true;
  BinaryFeatureOptions signature_features;
  GlobalDescriptorOptions signature_appearance;
  // Relate a key-image and the current image by wide-baseline matching when tracking fails at once.
  bool recover_gaps = true;
  // Match the last key-image with the first ones after the last frame; a circular graph on success.
  bool close_loop = true;

  // Fewest geometry inliers for relating two images by wide-baseline matching (gap recovery, loop closing). Lower
  // than n: σ_p already penalises geometries supported by few points, and a gap arc keeps the graph connected.
  int min_matched_inliers = 20;
  // The same for closing a loop, stricter: a wrong loop closure is worse than none.
  int min_loop_inliers = 30;
  // Fewest samples of the robust geometry of two images related by matching (gap arcs, loop candidates, link
  // witnesses, mapping by matching). The tracker's 20 (`geometry` below) are too few for matches: on kitti07 at 320
  // px, frames 32 and 36 (166 matches, 150 inliers) gave a motion 12.5 degrees off after 20 samples and the true one
  // after 100 (the estimator's default); frames 20 and 28 (47 matches) gave one 32 degrees off.
  int min_matched_samples = 100;
  // Keep a link made by matching (loop, gap) only when the drive after it confirms it (see above and
  // link_verification.h): a witness relates when its matching has min_matched_inliers within r_p, and it agrees when
  // its motion lies within the limits below of the link composed with the witness's own (tracked or, after a gap
  // arc, matched) motion from the end of the link. A look-alike place fools one pair of images, rarely also the pair
  // one arc further on. false: one pair suffices.
  bool verify_links = true;
  // How far a witness's rotation may lie from the composed one, degrees. A link counts as false when its rotation is
  // more than 5 degrees off the truth, a witness composes two geometries: half of that. The witnesses of the true
  // links of the simulator tests disagree by 0.1-0.8 degrees.
  double max_link_rotation_disagreement_deg = 2.5;
  // The same for the translation direction: degrees from the directions the composition allows for any positive
  // scales of its two parts (each geometry has its own unit). A link counts as false when its direction is more
  // than 10 degrees off; the witnesses of the true links of the simulator tests disagree by 0.6-5.1 degrees.
  double max_link_direction_disagreement_deg = 10.0;
  // A witness whose own geometry disagrees takes a second look: its matches estimated again from the composed
  // motion. It agrees when they fit that motion (refined on them) within TwoViewOptions::guess_preference of the
  // best sampled one and the refined motion lies within the limits above: the pair cannot tell the two apart. With
  // few matches over a long baseline at low resolution, a pair fits a family of motions several degrees apart
  // (rotation traded for translation) almost equally well. false: the sampled geometry alone decides.
  bool second_look = true;
  // A geometry whose pair does not tell the motions of a plane apart (most inliers on one plane, and another motion
  // of that plane fits the correspondences within TwoViewOptions::guess_preference of the estimate:
  // planar_degeneracy.h) does not determine the motion: on a pavement of identical slabs tracked arcs were 95-110
  // degrees off with σ_p 0.1 px. Teach writes no such arc (tracked, gap, loop, matching): the key-image is kept, the
  // map is disconnected there and the arc is reported with the reason (TeachStatistics::rejected_links). A tracked
  // arc carries the frames before it (each W(K, f) keeps W(K, f - 1) unless a sample fits better by
  // guess_preference) and is rejected only when the plane's other motion fits at least as well: in the town of
  // crossing121 a correct tracked arc (120 of 146 inliers on one plane) fits it at 1.06 times the cost. Witnesses of
  // links are not tested (kitti07 at 320 px every 4th frame: the witness of the true gap 140-144 fits the plane's
  // other motion alike and confirms on its second look). false: σ_p and the inlier count alone.
  bool reject_planar_geometry = true;
  // A geometry whose pair does not determine its direction of motion within max_link_direction_disagreement_deg is
  // not written either (tracked, gap, loop, matching, join): some direction that far from the estimate lies in the
  // `direction_confidence` likelihood-ratio confidence region of the direction (motion_uncertainty.h,
  // TestDirectionAt; σ from the pair's own residuals, no constant fitted to a data set). A tracked arc that the
  // feature fraction would end while its direction is undetermined goes on instead, as long as the paper's n
  // features and σ_p <= r_p hold (the baseline grows, and with it what the pair determines); only then is it
  // rejected. On a plane of fine ground texture (teacher_degenerate_test) a tracked arc of 0.8 m (52 inliers) was
  // 15.9 degrees off and gap arcs of 26-29 matches 12 and 51 degrees off, all with a direction 10 degrees away inside
  // the region; in the validation matrix (62 drives, 2667 arcs) the test rejects the tracked arc of hard126's frames
  // 131-147 (31 degrees off) and extends one correct arc of seed109 by a frame. false: no such test.
  bool reject_undetermined_direction = true;
  double direction_confidence = 0.95;

  FeatureTrackerOptions tracker;
  CornerDetectorOptions detector;
  // Two-view geometry of W(K, f). Tracked correspondences have few outliers, so the adaptive sampling may stop
  // after few samples (the estimator's default minimum is meant for matches).
  // The previous frame's geometry is the guess of each estimate (TwoViewOptions::guess_preference), without fewer
  // samples: a guess taken over from an unreliable first frame of a subrange must not stop the sampling early.
  TwoViewOptions geometry = [] {
    TwoViewOptions o;
    o.ransac.min_iterations = 20;
    o.ransac.min_iterations_with_guess = 20;
    return o;
  }();
  // Wide-baseline matching for gap recovery and loop closing. The ratio is looser than the paper's 0.6 (§4.1)
  // because every match must also agree with a robustly estimated two-view geometry: on 320x240 images 9 m apart,
  // 0.6 keeps too few matches to estimate one (17 against 44 with 0.8 in the simulated town).
  WideBaselineOptions matching = [] {
    WideBaselineOptions o;
    o.ratio = 0.8;
    return o;
  }();

  // Linking an appended drive to the map (AppendTo): existing key-images related by matching per key-image of the
  // drive, the closest in appearance first, and the least similarity S_ij a join keeps (Booij 2007 §B.2: 0.05).
  int join_candidates = 4;
  double min_join_similarity = 0.05;
  // A join links one place: its length, measured in units of an arc of the new drive at A (the depths at A of points
  // both reconstruct, design §3.3), must not exceed this many such arcs. In the simulated town true joins measure
  // In the simulated town (teacher_join_test) the true joins measured 0.15-0.63 arcs (0.1-1.7 m apart); two false
  // candidates (a street seen from 56 m further back, a look-alike street 134 m away) shared fewer than 5 points with
  // the arc, and a join whose length cannot be measured is not made.
  double max_join_length_arcs = 3.0;
  // A join inlier and a feature of A's arc are one physical point within this distance in A (pixels at
  // reference_width).
  double join_point_radius_px = 1.0;

  bool Check(std::string* error = nullptr) const;
};

// Why a key-image was registered.
enum class KeyImageReason { kStart, kSigmaP, kFeatures, kGap, kEnd, kDisconnected, kMatching };
const char* KeyImageReasonName(KeyImageReason reason);

// A link that wide-baseline matching proposed but verification turned down (TeachOptions::verify_links), or an arc
// whose geometry one plane explains (TeachOptions::reject_planar_geometry).
struct RejectedLink {
  std::string kind;  // "loop", "gap", "tracking", "matching" or "join"
  node_t from = kInvalidNodeId;
  node_t to = kInvalidNodeId;
  int64_t from_frame = -1;  // source frames of the two key-images
  int64_t to_frame = -1;
  int inliers = 0;    // of the link's own geometry
  int trackable = 0;  // its matches the tracker follows (the features the arc would have kept)
  double sigma_p = 0.0;
  std::string reason;
};

struct TeachStatistics {
  int frames = 0;
  int key_images = 0;
  std::array<int, 7> key_images_by_reason{};  // indexed by KeyImageReason
  int gaps_recovered = 0;
  int gaps_unrecovered = 0;
  bool loop_closed = false;
  // Appended drives (Teacher::AppendTo): join arcs made to the existing graph, and key-images of the drive with
  // none.
  int joins = 0;
  int key_images_without_join = 0;
  // Link candidates whose own geometry was acceptable but which the drive around them did not confirm.
  std::vector<RejectedLink> rejected_links;
  // Wall time per stage, seconds.
  double seconds_pyramid = 0, seconds_tracking = 0, seconds_geometry = 0, seconds_detection = 0,
         seconds_matching = 0, seconds_storage = 0;
};

class Teacher {
 public:
  // `camera` describes the frames given to AddFrame (already at their working resolution). `database` may be
  // null: the map is then only kept in memory.
  Teacher(const CameraModel& camera, const TeachOptions& options, MapDatabase* database);
  ~Teacher();

  // Makes this drive the next route of `existing` (a map read with its key-images; it must outlive the teacher):
  // ids after the map's, MapNode::route one more than the map's largest, and Finish() links the drive to it (see
  // the top of this file). Call before the first frame. The database, when given, must hold `existing` already.
  void AppendTo(const Map& existing);

  // Processes the next frame (8-bit gray, camera-sized). frame.source_index names it in the teach sequence.
  void AddFrame(const Frame& frame);
  // Registers the last frame as a key-image, closes the loop and, after AppendTo, links the drive to the existing
  // map. Call once, after the last frame.
  void Finish();

  const Map& map() const { return map_; }
  const TeachStatistics& statistics() const { return statistics_; }
  // Thresholds in pixels of the frames given, after scaling to their width.
  double sigma_p_threshold_px() const { return max_sigma_p_px_; }

 private:
  struct FrameState;
  struct Subrange;
  struct PendingGap;

  // Two-view geometry between the subrange's key-image and `frame` from the features tracked since the key-image.
  void EstimateGeometryToKey(FrameState* frame);
  bool GeometryAcceptable(const FrameState& frame) const;
  // Whether the tracked arc to `frame` would be rejected (UndeterminedMotion; computed once per frame).
  bool TrackedArcUndetermined(FrameState* frame) const;
  // An arc that the feature fraction would end (TeachOptions::min_features_fraction) while its pair does not yet
  // determine its motion goes on to `frame` as long as the paper's n features and σ_p <= r_p hold: the baseline grows
  // and with it what the pair determines (TeachOptions::reject_undetermined_direction).
  bool ExtendsUndeterminedArc(FrameState* frame) const;
  // Registers `frame` as key-image: the arc from the current key-image (when `with_arc`), the node with its
  // observations (tracked features plus new corners), the scale at the previous key-image; then starts a subrange.
  // `matched`: the frame prepared for matching, when a gap arc reaches it (it may witness the gap arc before).
  void RegisterKeyImage(FrameState* frame, KeyImageReason reason, bool with_arc,
                        const MatchableImage* matched = nullptr);
  // Relates the current key-image and `frame` by wide-baseline matching; on success registers `frame` as a key-image
  // reached by a "gap" arc, held back until the images after it confirm it (ResolvePendingGap). Returns false when
  // the two images cannot be related (or the key-image before the gap contradicts the relation).
  bool RecoverGap(FrameState* frame);
  // Weighs the held-back gap arc K -> G with the images after G (the frames tracked from G, the key-image after G
  // when a gap arc reaches it; the last one that relates to K decides) and commits it when they confirm it; otherwise
  // rejects it (the map stays disconnected at G). `next`: the tracked arc from G to the key-image just registered
  // (null when there is none; the relative scale at G needs it).
  void ResolvePendingGap(const MapArc* next);
  // What a witness of a link says (link_verification.h).
  enum class WitnessVerdict { kConfirms, kContradicts, kUnrelated };
  // Matches X with Z and compares the measured motion with `y_from_x` followed by `z_from_y`; `description` says
  // what was found, for the report. `scale`: the length of `z_from_y` over that of `y_from_x`, when known (the
  // composition then allows one translation direction, link_verification.h).
  WitnessVerdict WeighWitness(const MatchableImage& x, const MatchableImage& z, const Rigid3d& y_from_x,
                              const Rigid3d& z_from_y, const std::string& name, std::string* description,
                              std::optional<double> scale = std::nullopt);
  // Starts a subrange at `frame`: references redefined there, new corners detected.
  void StartSubrange(FrameState* frame);
  void CloseLoop();
  // Links the drive's key-images to the existing map (AppendTo): the join arcs.
  void JoinRoutes();
  node_t NextNodeId() const { return first_node_id_ + static_cast<node_t>(map_.nodes().size()); }
  arc_t NextArcId() const { return first_arc_id_ + static_cast<arc_t>(map_.arcs().size()); }
  void BuildByMatching();
  // Mapping by matching: relates frames a < b, inserting key-images between them where needed.
  void RelateFramesByMatching(size_t a, size_t b);
  MatchableImage& MatchableFrame(size_t index);
  MatchedGeometryOptions MatchingOptions() const;
  // The geometry options of a witness's second look (WeighWitness).
  TwoViewOptions SecondLookOptions() const;
  bool AcceptableMatchedGeometry(const MatchedGeometry& matched, int min_inliers) const;
  // Whether the correspondences leave the motion of `geometry` undetermined: one plane explains its inliers and
  // another motion of that plane fits alike (planar_degeneracy.h; TeachOptions::reject_planar_geometry), or a
  // direction beyond the link limit lies in its confidence region (motion_uncertainty.h;
  // TeachOptions::reject_undetermined_direction). `description` says why, for the report.
  // `tracked`: a tracked W(K, f), which the plane's other motion must fit at least as well (not only alike).
  bool UndeterminedMotion(const std::vector<Vector3d>& bearings_a, const std::vector<Vector3d>& bearings_b,
                          const TwoViewGeometry& geometry, std::string* description, bool tracked = false) const;
  MatchableImage PrepareForMatching(const cv::Mat& image) const;
  void Commit(const MapNode* node, const MapArc* arc, const std::vector<NodeScale>& scales,
              const std::vector<std::pair<node_t, std::vector<FeatureObservation>>>& extra_observations);

  std::unique_ptr<CameraModel> camera_;
  TeachOptions options_;
  MapDatabase* database_;
  Map map_;
  TeachStatistics statistics_;

  double max_sigma_p_px_;
  TwoViewOptions geometry_options_;
  CornerDetectorOptions detector_options_;
  ImagePyramidOptions pyramid_options_;
  FeatureTracker tracker_;

  std::unique_ptr<FrameState> previous_;
  std::unique_ptr<Subrange> subrange_;
  // Depth of every inlier of the last arc in its `to` key-image (for the relative scale at that node).
  arc_t last_arc_ = kInvalidArcId;
  std::unordered_map<feature_t, double> last_arc_depth_at_to_;
  feature_t next_feature_id_ = 0;
  bool finished_ = false;
  // AppendTo: the map this drive is added to, the drive's route number and the first ids it uses.
  const Map* existing_ = nullptr;
  int route_ = 0;
  node_t first_node_id_ = 0;
  arc_t first_arc_id_ = 0;
  // The gap arc waiting for the key-image after it (TeachOptions::verify_links).
  std::unique_ptr<PendingGap> pending_gap_;

  // Mapping by matching: the buffered frames, their prepared images, the node of each key-image frame, and the
  // feature id given to a key-point (frame, key-point index).
  std::vector<Frame> frames_;
  std::unordered_map<size_t, MatchableImage> matchable_frames_;
  std::unordered_map<size_t, node_t> node_of_frame_;
  std::map<std::pair<size_t, int>, feature_t> feature_of_keypoint_;
};

}  // namespace retrace
