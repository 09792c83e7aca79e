#include "retrace/repeat/localizer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <tuple>

#include <spdlog/spdlog.h>

#include "retrace/control/steering.h"
#include "retrace/geometry/absolute_pose.h"
#include "retrace/geometry/relative_pose.h"
#include "retrace/geometry/triangulation.h"
#include "retrace/map/descriptor_coding.h"
#include "retrace/repeat/localizer_internal.h"
#include "retrace/util/error.h"

namespace retrace {
namespace {

// A lookup table by feature id from (id, value) pairs in any order; a repeated id keeps its last value, as
// assignment into a map would.
template <typename Value>
boost::container::flat_map<feature_t, Value> SortedById(std::vector<std::pair<feature_t, Value>> entries) {
  std::stable_sort(entries.begin(), entries.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<std::pair<feature_t, Value>> unique;
  unique.reserve(entries.size());
  for (size_t i = 0; i < entries.size(); ++i) {
    if (i + 1 < entries.size() && entries[i + 1].first == entries[i].first) continue;
    unique.push_back(std::move(entries[i]));
  }
  return boost::container::flat_map<feature_t, Value>(boost::container::ordered_unique_range, unique.begin(),
                                                      unique.end());
}

}  // namespace

double internal::Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + mid, values.end());
  return values[mid];
}

const char* LocalizerStateName(LocalizerState state) {
  switch (state) {
    case LocalizerState::kTracking:
      return "tracking";
    case LocalizerState::kLost:
      return "lost";
    case LocalizerState::kRelocalizing:
      return "relocalizing";
  }
  return "?";
}

bool LocalizerOptions::Check(std::string* error) const {
  const auto fail = [&](const std::string& message) {
    if (error != nullptr) *error = message;
    return false;
  };
  if (reference_width <= 0) return fail("reference_width must be positive");
  if (!(smoothing_sigma_px >= 0)) return fail("smoothing_sigma_px must be >= 0");
  if (!(max_residual > 0)) return fail("max_residual (R) must be positive");
  if (!(max_sigma_p_px > 0)) return fail("max_sigma_p_px must be positive");
  if (!(inlier_threshold_px > 0)) return fail("inlier_threshold_px must be positive");
  if (!(next_arc_ratio > 0) || !(previous_arc_ratio > 0)) return fail("prudence ratios must be positive");
  if (!(prediction_radius_px > 0) || !(prediction_scale_ratio >= 1)) return fail("invalid prediction acceptance");
  if (!(max_drift_px > 0)) return fail("max_drift_px must be positive");
  if (!(backward_margin >= 0)) return fail("backward_margin must be >= 0");
  if (!(min_parallax_px >= 0)) return fail("min_parallax_px must be >= 0");
  if (!(agreement_sigmas > 0)) return fail("agreement_sigmas must be positive");
  if (!(multi_view_max_residual_px > 0)) return fail("multi_view_max_residual_px must be positive");
  std::string belief_error;
  if (!belief.Check(&belief_error)) return fail("belief: " + belief_error);
  std::string placement_error;
  if (!placement.Check(&placement_error)) return fail("placement: " + placement_error);
  std::string path_error;
  if (!path.Check(&path_error)) return fail("path: " + path_error);
  std::string lateral_error;
  if (!lateral_filter.Check(&lateral_error)) return fail("lateral_filter: " + lateral_error);
  if (retry_interval < 1) return fail("retry_interval must be >= 1");
  if (min_features < 8) return fail("min_features must be >= 8");
  if (max_bad_frames < 1) return fail("max_bad_frames must be >= 1");
  if (min_bootstrap_inliers < 8 || min_binary_inliers < 8 || min_bootstrap_features < 8) {
    return fail("bootstrap minima must be >= 8");
  }
  if (guided_matching_min_inliers < 0) return fail("guided_matching_min_inliers must be >= 0 (0: off)");
  if (bootstrap_alternative_starts < 0 || start_alternative_starts < 0) {
    return fail("bootstrap_alternative_starts and start_alternative_starts must be >= 0 (0: off)");
  }
  if (prediction_skipped_levels < 0) return fail("prediction_skipped_levels must be >= 0");
  if (relocalization_neighbourhood < 0 || relocalization_widening < 0) {
    return fail("relocalization_neighbourhood and relocalization_widening must be >= 0");
  }
  if (global_relocalization_frames < 1) return fail("global_relocalization_frames must be >= 1");
  if (min_global_agreeing_key_images < 1) return fail("min_global_agreeing_key_images must be >= 1");
  if (!(global_features_per_log_candidates >= 0.0) || global_gate_candidates < 1) {
    return fail("global_features_per_log_candidates must be >= 0 and global_gate_candidates >= 1");
  }
  if (single_key_image_gate_candidates < 0) return fail("single_key_image_gate_candidates must be >= 0");
  if (max_cached_key_images < 1) return fail("max_cached_key_images must be >= 1");
  if (max_resident_signatures < 0) return fail("max_resident_signatures must be >= 0");
  if (retrieval_shortlist < 0 || start_retrieval_shortlist < 0 || retrieval_confident_inliers < 0) {
    return fail("retrieval_shortlist, start_retrieval_shortlist and retrieval_confident_inliers must be >= 0");
  }
  std::string retrieval_error;
  if (!retrieval.Check(&retrieval_error)) return fail("retrieval: " + retrieval_error);
  if (!(bootstrap_neighbour_radius_px > 0) || !(bootstrap_radius_px > 0)) return fail("invalid bootstrap radii");
  if (!tracker.Check()) return fail("invalid tracker options");
  if (!geometry.Check()) return fail("invalid geometry options");
  std::string pose_error;
  if (!pose.Check(&pose_error)) return fail("pose: " + pose_error);
  std::string matching_error;
  if (!matching.Check(&matching_error)) return fail("matching: " + matching_error);
  if (!relocalization_features.Check(&matching_error)) return fail("relocalization_features: " + matching_error);
  if (!vocabulary.Check(&matching_error)) return fail("vocabulary: " + matching_error);
  if (!(retrieval_ambiguity_ratio >= 0.0 && retrieval_ambiguity_ratio <= 1.0)) {
    return fail("retrieval_ambiguity_ratio must be in [0, 1]");
  }
  if (relocalization_frame_keypoints < 8) return fail("relocalization_frame_keypoints must be >= 8");
  if (relocalization_max_samples < 1) return fail("relocalization_max_samples must be >= 1");
  if (!(steering_half_field_deg > 0 && steering_half_field_deg < 90)) {
    return fail("steering_half_field_deg must be in (0, 90)");
  }
  return true;
}

Localizer::Localizer(Map map, const CameraModel& camera, const LocalizerOptions& options)
    : camera_(camera.Clone()),
      options_(options),
      map_(std::move(map)),
      appearance_index_(options.retrieval),
      belief_(map_, options.belief) {
  std::string error;
  if (!options_.Check(&error)) throw std::invalid_argument("LocalizerOptions: " + error);
  pixel_scale_ = static_cast<double>(camera.width()) / options_.reference_width;
  lateral_window_ = ObservationWindow(options_.lateral_filter);
  max_sigma_p_px_ = options_.max_sigma_p_px * pixel_scale_;
  pyramid_options_ = TrackingPyramidOptions(camera.width(), options_.reference_width, options_.smoothing_sigma_px);
  geometry_options_ = options_.geometry;
  geometry_options_.ransac.max_error_px = options_.inlier_threshold_px * pixel_scale_;
  geometry_options_.min_parallax_px = options_.min_parallax_px * pixel_scale_;
  pose_options_ = options_.pose;
  pose_options_.ransac.max_error_px = options_.inlier_threshold_px * pixel_scale_;
  FeatureTrackerOptions tracker_options = options_.tracker;
  tracker_options.alignment.max_residual = options_.max_residual;
  tracker_options.alignment.affine_fallback = options_.affine_fallback;
  tracker_options.alignment.affine_refinement = options_.affine_refinement;
  tracker_options.num_levels = pyramid_options_.num_levels;
  tracker_options.robust_acquired_tracking = options_.relocalization_robust_alignment;
  tracker_ = FeatureTracker(tracker_options);
  refine_options_.alignment = options_.tracker.alignment;
  refine_options_.alignment.max_residual = options_.max_residual;
  refine_options_.alignment.affine_fallback = options_.affine_fallback;
  refine_options_.alignment.scale_prior_sigma = 0.0;
  refine_options_.max_distance = options_.prediction_radius_px * pixel_scale_;
  refine_options_.max_scale_ratio = options_.prediction_scale_ratio;
  if (options_.path.camera_height > 0) path_ = std::make_unique<TaughtPath>(map_, camera, options_.path);
  relocalization_matching_ = options_.matching;
  relocalization_geometry_ = geometry_options_;
  frame_features_ = options_.relocalization_features;
  frame_features_.max_keypoints = options_.relocalization_frame_keypoints;
  frame_features_.scale_with_area = true;
  if (options_.binary_relocalization) {
    relocalization_matching_.ratio = options_.relocalization_features.ratio;
    relocalization_matching_.cross_check = options_.relocalization_features.cross_check;
    relocalization_geometry_.ransac.max_iterations =
        std::max(relocalization_geometry_.ransac.min_iterations, options_.relocalization_max_samples);
  }

  for (const MapNode& node : map_.nodes()) {
    // Images held by the map are checked now, those it reads on demand when they are read (NodeImage).
    if (!map_.HasKeyImage(node.id)) throw InputError("map", "key-image " + std::to_string(node.id) + " is not loaded");
    if (!node.image.empty()) CheckKeyImageSize(node.id, node.image);
    auto data = std::make_unique<NodeData>();
    data->node = &node;
    std::vector<std::pair<feature_t, Vector2d>> positions;
    std::vector<std::pair<feature_t, Vector3d>> bearings;
    positions.reserve(node.features.size());
    bearings.reserve(node.features.size());
    for (const FeatureObservation& f : node.features) {
      Vector3d bearing;
      if (!camera_->Unproject(f.position, &bearing)) continue;
      positions.emplace_back(f.feature_id, f.position);
      bearings.emplace_back(f.feature_id, bearing);
    }
    data->positions = SortedById(std::move(positions));
    data->bearings = SortedById(std::move(bearings));
    nodes_[node.id] = std::move(data);
    // Retrieval: the stored appearance when it was made with these options (its size tells the thumbnail's width;
    // LoadMapForLocalizer drops signatures made with other settings), else computed now (0.1 ms per key-image).
    cv::Mat appearance = node.signature.appearance;
    if (appearance.empty() || appearance.cols != options_.retrieval.width) {
      appearance = QuantizeGlobalDescriptor(ComputeGlobalDescriptor(NodeImage(node.id), options_.retrieval));
    }
    appearance_entry_[node.id] = appearance_index_.Add(appearance);
    appearance_nodes_.push_back(node.id);
  }
  // Entry i of the words' index is the i-th node, as in the appearance index above.
  if (!map_.visual_words() || map_.visual_words()->index.size() != map_.nodes().size()) {
    map_.SetVisualWords(BuildMapVisualWords(map_, options_));
  }
  for (const MapArc& arc : map_.arcs()) {
    auto data = std::make_unique<ArcData>();
    data->arc = &arc;
    for (const ArcPoint& p : arc.points) data->points[p.feature_id] = p.point_in_from;
    // Linear and circular routes: the neighbouring arcs continue the chain (first one found, not straight back).
    for (const MapArc* next : map_.ArcsFrom(arc.to)) {
      if (next->to != arc.from) {
        data->next = next->id;
        break;
      }
    }
    for (const MapArc* previous : map_.ArcsTo(arc.from)) {
      if (previous->from != arc.to) {
        data->previous = previous->id;
        break;
      }
    }
    // The camera is placed between the bisecting planes of the arc's nodes where the drive goes on through them
    // along exactly one driven arc (placement.h); at a route's end, a junction, or on a link, the paper's plane.
    const auto only_driven = [&arc](const std::vector<const MapArc*>& arcs) -> const Rigid3d* {
      const MapArc* found = nullptr;
      for (const MapArc* other : arcs) {
        if (other->IsLink() || other->id == arc.id || (other->from == arc.to && other->to == arc.from)) continue;
        if (found != nullptr) return nullptr;
        found = other;
      }
      return found != nullptr ? &found->to_from_from : nullptr;
    };
    if (!arc.IsLink()) {
      data->bounds =
          BisectingBounds(arc.to_from_from, only_driven(map_.ArcsTo(arc.from)), only_driven(map_.ArcsFrom(arc.to)));
      // Across a gap in the map: the piece the teach drive made next (before), for the relocalization window.
      if (data->next == kInvalidArcId) data->next_piece = map_.DrivenArcAcrossGap(arc.to, +1);
      if (data->previous == kInvalidArcId) data->previous_piece = map_.DrivenArcAcrossGap(arc.from, -1);
    }
    arcs_[arc.id] = std::move(data);
  }
  if (options_.multi_view_points) RefineArcPointsMultiView();
}

void Localizer::RefineArcPointsMultiView() {
  // An arc's points are refined from its own points and the key-images' bearings only, in place.
  int points = 0, with_more_views = 0, changed = 0;
  for (const auto& [id, data] : arcs_) {
    if (data->arc->IsLink()) continue;
    // The key-images that may see the arc's points, as cameras in its frame and unit (a at the origin).
    const std::vector<std::pair<node_t, Rigid3d>> cameras = KeyImagesInArcFrame(*data);
    for (auto& [feature, point] : data->points) {
      ++points;
      std::vector<Rigid3d> poses;
      std::vector<Vector3d> bearings;
      for (const auto& [node, pose] : cameras) {
        const NodeData& node_data = *nodes_.at(node);
        const auto bearing = node_data.bearings.find(feature);
        if (bearing == node_data.bearings.end()) continue;
        poses.push_back(pose);
        bearings.push_back(bearing->second);
      }
      if (poses.size() < 3) continue;
      ++with_more_views;
      Vector3d better;
      double worst = 0.0;
      if (!RefinePointMultiView(poses, bearings, point, camera_->FocalLength(), &better, &worst) ||
          worst > options_.multi_view_max_residual_px * pixel_scale_) {
        continue;
      }
      point = better;
      ++changed;
    }
  }
  spdlog::debug("repeat: {} of {} arc points seen by three or more key-images, {} triangulated again from them",
                with_more_views, points, changed);
}

Localizer::~Localizer() = default;

void Localizer::SetStartArc(arc_t arc) {
  if (Arc(arc) == nullptr) throw InputError("start arc", "the map has no arc " + std::to_string(arc));
  start_arc_ = arc;
  belief_.ResetTo(arc);  // the user says where the drive starts
}

Localizer::NodeData& Localizer::Node(node_t id) { return *nodes_.at(id); }

const Localizer::ArcData* Localizer::Arc(arc_t id) const {
  const auto it = arcs_.find(id);
  return it == arcs_.end() ? nullptr : it->second.get();
}

void Localizer::CheckKeyImageSize(node_t id, const cv::Mat& image) const {
  if (image.cols != camera_->width() || image.rows != camera_->height()) {
    throw InputError("map", fmt::format("key-image {} is {}x{} but the camera is {}x{}", id, image.cols, image.rows,
                                        camera_->width(), camera_->height()));
  }
}

cv::Mat Localizer::NodeImage(node_t id) const {
  cv::Mat image = map_.KeyImage(id);
  if (image.empty()) throw InputError("map", "key-image " + std::to_string(id) + " is not loaded");
  CheckKeyImageSize(id, image);
  return image;
}

const ImagePyramid& Localizer::NodePyramid(node_t id) {
  NodeData& node = Node(id);
  node.last_used = frame_counter_;
  if (!node.pyramid) node.pyramid = std::make_unique<ImagePyramid>(NodeImage(id), pyramid_options_);
  return *node.pyramid;
}

const WideBaselineFeatures& Localizer::NodeWideBaseline(node_t id) {
  NodeData& node = Node(id);
  node.last_used = frame_counter_;
  if (!node.wide_baseline && !options_.binary_relocalization) {
    node.wide_baseline = ExtractWideBaselineFeatures(NodeImage(id), options_.matching);
  } else if (!node.wide_baseline) {
    KeyImageSignature signature = map_.Signature(id);  // held by the map, or read from its file
    ResolveSignature(map_, id, options_, &signature);
    if (!signature.descriptors.empty() || (signature.keypoints.empty() && !signature.appearance.empty())) {
      // Stored by teach (the descriptors shared, not copied).
      node.wide_baseline = WideBaselineFeatures{std::move(signature.keypoints), signature.descriptors};
    } else {
      node.wide_baseline = ExtractBinaryFeatures(NodeImage(id), options_.relocalization_features);
    }
  }
  return *node.wide_baseline;
}

KeyImageSignature Localizer::ComputeSignature(const cv::Mat& image, const LocalizerOptions& options) {
  KeyImageSignature signature;
  WideBaselineFeatures features = ExtractBinaryFeatures(image, options.relocalization_features);
  signature.keypoints = std::move(features.keypoints);
  signature.keypoints.shrink_to_fit();  // the detector's growth doubled them (32 MB on 1264 key-images)
  signature.descriptors = features.descriptors;
  signature.appearance = QuantizeGlobalDescriptor(ComputeGlobalDescriptor(image, options.retrieval));
  return signature;
}

void Localizer::ResolveSignature(const Map& map, node_t id, const LocalizerOptions& options,
                                 KeyImageSignature* signature) {
  if (signature->descriptor_residual.empty()) return;
  const cv::Mat key_image = map.KeyImage(id);
  signature->descriptors = cv::Mat();
  if (!key_image.empty() && key_image.type() == CV_8UC1 &&
      DecodeDescriptorResidual(signature->descriptor_residual,
                               DescribeBinaryKeyPoints(key_image, signature->keypoints, options.relocalization_features),
                               &signature->descriptors)) {
    signature->descriptors = cv::Mat();
  }
  signature->descriptor_residual.clear();
}

std::shared_ptr<const VisualWords> Localizer::BuildMapVisualWords(const Map& map, const LocalizerOptions& options) {
  if (!options.binary_relocalization || !options.visual_word_retrieval) return nullptr;
  // Signatures held by the map, or read from its file one at a time (40 MB of descriptors for 1264 key-images).
  const std::vector<MapNode>& nodes = map.nodes();
  const auto descriptors = [&](size_t i) {
    KeyImageSignature signature = map.Signature(nodes[i].id);
    ResolveSignature(map, nodes[i].id, options, &signature);
    return signature.descriptors;
  };
  auto words = std::make_shared<const VisualWords>(BuildVisualWords(nodes.size(), descriptors, options.vocabulary));
  // One word: no stored descriptors (a map given without signatures), or too few to tell key-images apart.
  return words->vocabulary.size() > 1 ? words : nullptr;
}

std::shared_ptr<const ReferencePatch> Localizer::Reference(node_t node_id, feature_t feature) {
  NodeData& node = Node(node_id);
  node.last_used = frame_counter_;
  auto it = node.references.find(feature);
  if (it == node.references.end()) {
    std::shared_ptr<ReferencePatch> patch;
    const auto position = node.positions.find(feature);
    if (position != node.positions.end()) {
      patch = std::make_shared<ReferencePatch>();
      // The affine warp's matrix (ReferencePatch::AffineInverseHessian) is computed at its first use, once per
      // patch: most references cut here only ever check a prediction, with the paper's warp.
      // A key-image's pyramid is built once (NodePyramid): the patch may keep a handle to its level 0.
      if (!patch->Create(NodePyramid(node_id), position->second, tracker_.Options().alignment.window_size,
                         tracker_.Options().num_levels, AlignmentOptions().scale_window_stride,
                         ReferencePatch::PatchImage::kKept)) {
        patch.reset();
      }
    }
    it = node.references.emplace(feature, std::move(patch)).first;
  }
  return it->second;
}

node_t Localizer::ReferenceNode(const ArcData& arc, feature_t feature, node_t preferred) const {
  const node_t other = preferred == arc.arc->from ? arc.arc->to : arc.arc->from;
  if (nodes_.at(preferred)->positions.count(feature)) return preferred;
  if (nodes_.at(other)->positions.count(feature)) return other;
  return kInvalidNodeId;
}

void Localizer::ClearTracks() {
  for (const TrackedFeature& f : std::vector<TrackedFeature>(tracker_.Features())) tracker_.Remove(f.id);
  last_geometry_.clear();
  last_pose_.reset();
  reference_node_.clear();
  retry_after_.clear();
}

FrameResult Localizer::ProcessFrame(const Frame& frame) {
  const auto start = std::chrono::steady_clock::now();
  if (frame.image.cols != camera_->width() || frame.image.rows != camera_->height() ||
      frame.image.type() != CV_8UC1) {
    throw InputError(frame.name, "image is " + std::to_string(frame.image.cols) + "x" +
                                     std::to_string(frame.image.rows) + " 8-bit gray expected " +
                                     std::to_string(camera_->width()) + "x" + std::to_string(camera_->height()));
  }
  ++frame_counter_;
  if (state_ == LocalizerState::kLost) state_ = LocalizerState::kRelocalizing;
  FrameResult result;
  result.frame_index = frame.index;
  pyramid_.Build(frame.image, pyramid_options_);
  prediction_pyramid_ = pyramid_.FinestLevels(pyramid_.NumLevels() - options_.prediction_skipped_levels);
  // The belief moves with the camera whatever this frame shows (motion model, belief.h).
  belief_.Predict(1);
  belief_updated_ = false;
  frame_placement_.reset();

  if (state_ == LocalizerState::kTracking) {
    const int before = tracker_.NumFeatures();
    tracker_.Track(pyramid_);
    result.dropped += before - tracker_.NumFeatures();
    for (auto it = reference_node_.begin(); it != reference_node_.end();) {
      it = tracker_.Find(it->first) == nullptr ? reference_node_.erase(it) : std::next(it);
    }
    Localize(&result);
  }
  // Not localized (before, or the tracks given up in this very frame): re-initialise from this frame, so that a
  // loss costs no extra frame. A frame that could not be re-initialised is `lost`, the following ones
  // `relocalizing` until one succeeds.
  if (state_ != LocalizerState::kTracking) {
    if (Bootstrap(frame, &result)) {
      state_ = LocalizerState::kTracking;
      bad_frames_ = 0;
      result.bootstrapped = true;
      result.sigma_p_from = result.sigma_p_to = result.sigma_p = -1.0;
      Localize(&result);
    }
  }
  std::optional<PlaceMeasurement> evidence_alone;  // this frame's only evidence, when it is a resected placement
  if (!belief_updated_) {
    // A bootstrap that failed may still have placed the camera by the key-images it verified
    // (PlaceByVerifiedKeyImages). The placements of consecutive frames rest on the same key-images' matches seen from
    // nearly the same place, and share their error (the validation drive beside111's, frames 129-137, lay mostly 1-3
    // teach frames ahead of the truth): k of them in a row carry about the information of one, so the k-th is given
    // σ √k — otherwise the belief grew confident on the arc ahead of the camera.
    std::vector<PlaceMeasurement> measurements;
    if (verified_placement_) {
      ++verified_placements_in_a_row_;
      measurements.push_back(*verified_placement_);
      measurements.back().sigma *= std::sqrt(static_cast<double>(verified_placements_in_a_row_));
      evidence_alone = verified_placement_;
    } else {
      verified_placements_in_a_row_ = 0;
    }
    belief_.Update(measurements, frame_counter_);
  }
  if (state_ == LocalizerState::kTracking) verified_placements_in_a_row_ = 0;
  verified_placement_.reset();

  // The reported state follows the belief: `tracking` on the current arc only when the belief is confident that
  // the camera is there and this frame gave it evidence.
  const PlaceEstimate& estimate = belief_.estimate();
  result.belief_arc = estimate.arc;
  result.evidence = estimate.evidence;
  result.confidence = estimate.confidence;
  if (state_ == LocalizerState::kTracking) {
    result.confidence = belief_.Confidence(arc_);
    const std::optional<double> along = AlongCurrentArc();
    const bool confident = result.confidence >= options_.belief.min_confidence && estimate.evidence && along;
    // Across a gap in the map the arc the belief prefers may be the likelier right report (PlaceBelief::ReportedArc;
    // `scripts/validation --random 24 --random-seed 7`'s rand1706 frame 436, 3 m beside: tracks on the arc before a
    // two-frame gap at confidence 0.993, the camera already past the gap on the arc the belief preferred, 0.99998).
    const arc_t reported = confident ? belief_.ReportedArc(arc_) : arc_;
    if (reported != arc_ && Arc(reported) != nullptr) {
      ReportTracking(reported, estimate.along, estimate.sigma, estimate.confidence, &result);
    } else if (confident) {
      ReportTracking(arc_, *along, estimate.sigma * belief_.ArcLength(estimate.arc) / belief_.ArcLength(arc_),
                     result.confidence, &result);
    } else if (estimate.tracking && IsNeighbour(arc_, estimate.arc) && MeetAtANode(arc_, estimate.arc)) {
      // Near a node the belief may be confident in the neighbouring arc (its tolerance reaches back over the node)
      // and not in the tracked one, which the camera has not left yet (eq. (9)): a short last arc of a route, whose
      // tolerance is a few centimetres, leaves a camera standing just before its first key-image `lost` with over a
      // hundred features tracked. The belief's arc is reported — only when the two arcs meet at a node: across a gap
      // in the map (the belief's graph joins the pieces, IsNeighbour) the camera is not near the tracked arc's node,
      // and after a loss there the belief lagged on the piece before while the tracks were located on the next
      // (`scripts/validation --random 24`'s rand1114 frame 219 with `--multi-view-points`, two arcs off).
      ReportTracking(estimate.arc, estimate.along, estimate.sigma, estimate.confidence, &result);
    } else {
      result.state = LocalizerState::kLost;
    }
  } else if (estimate.tracking && Arc(estimate.arc) != nullptr &&
             (!evidence_alone ||
              belief_.MeasurementSupport(estimate.arc, *evidence_alone) >= options_.belief.min_confidence)) {
    // The tracks were given up in this frame after their placement was accepted: the frame has its own evidence
    // and the belief is confident, so it is reported on the belief's arc (the next frame relocalizes). Or the camera
    // was resected from the key-images a relocalization verified: its placement is coarse (a fraction of an arc,
    // PlacementModel::verified_pose_sigma_factor) and the belief carried on it by the motion model over several such
    // frames grew confident near nodes on the arc ahead (validation drives beside104, beside111: the camera 0.2-0.3
    // arc lengths before it), so the frame's own placement must put the camera on the arc as surely as the belief
    // (PlaceBelief::MeasurementSupport).
    ReportTracking(estimate.arc, estimate.along, estimate.sigma, estimate.confidence, &result);
  } else {
    result.state = state_;
  }
  // The camera relative to the taught path in metres, from this frame's usable absolute pose.
  if (result.state == LocalizerState::kTracking && path_ != nullptr && last_pose_ && last_pose_->usable &&
      last_pose_->frame == frame_counter_) {
    // The heading's σ from the rotation's covariance with the pose's residual noise floored, as the lateral offset's
    // in the recent frames' combination (FilterLateralOffset, LocalizerOptions::lateral_noise_floor_px).
    std::optional<PoseCovariance> covariance = last_pose_->covariance;
    if (covariance) covariance->rotation *= last_pose_->noise_floor_factor;
    result.path = path_->Locate(last_pose_->arc, last_pose_->current_from_from, covariance ? &*covariance : nullptr,
                                arc_);
  }
  if (result.state == LocalizerState::kTracking && result.path.valid) FilterLateralOffset(result.arc, &result.path);
  if (result.state != LocalizerState::kTracking) {
    lateral_window_.Clear();  // the combined offset starts again with the next tracked frame
    last_metric_.reset();
    result.position_valid = false;
    result.steering_valid = false;
    result.steering = 0.0;
  }
  FillCounts(&result);
  ReleaseUnusedKeyImages();
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

namespace {

// The factor that raises a pose's covariance to a residual noise of at least `floor_px` per component: the
// covariance is the residual variance per component, sum of squares / (2n - 6), times (JᵀJ)⁻¹ (AbsolutePose).
double NoiseFloorFactor(const AbsolutePose& pose, double floor_px) {
  const double n = static_cast<double>(pose.num_inliers);
  if (!(floor_px > 0) || !(n > 3) || !std::isfinite(pose.rms_residual_px)) return 1.0;
  const double variance = pose.rms_residual_px * pose.rms_residual_px * 2.0 * n / (2.0 * n - 6.0);
  return variance > 0 ? std::max(1.0, floor_px * floor_px / variance) : 1.0;
}

}  // namespace

void Localizer::FilterLateralOffset(arc_t arc, PathPose* path) {
  // The distance driven since the last frame with a metric path: along the same arc, or across its end into the
  // next; anything else (a jump, a backward transition, the first frame) starts the window again.
  std::optional<double> step;
  if (last_metric_ && last_metric_->arc == arc) {
    step = path->along_m - last_metric_->along_m;
  } else if (last_metric_) {
    const std::vector<arc_t>& next = belief_.Successors(last_metric_->arc);
    if (std::find(next.begin(), next.end(), arc) != next.end()) step = last_metric_->to_next_m + path->along_m;
  }
  last_metric_ = MetricPlace{arc, path->along_m, path->to_next_m};
  if (!(options_.lateral_filter.process_sigma > 0) || !(options_.lateral_filter.window > 0)) return;  // the own
  if (!step) {
    lateral_window_.Clear();
  } else {
    travelled_m_ += std::abs(*step);  // the walk's variance grows with the distance driven, either way
  }
  // The frame's σ with the pose's residual noise floored (LocalizerOptions::lateral_noise_floor_px): the part from
  // the arc's scale, |lateral| · scale σ, stays as it is.
  const double scale_part = path->lateral_m * path->scale_sigma;
  const double pose_part = std::max(0.0, path->lateral_sigma_m * path->lateral_sigma_m - scale_part * scale_part);
  const double factor = last_pose_ ? last_pose_->noise_floor_factor : 1.0;
  lateral_window_.Add(travelled_m_, path->lateral_m, std::sqrt(scale_part * scale_part + factor * pose_part),
                      arc);
  const CombinedObservation combined = lateral_window_.Combine();
  if (!combined.valid) return;
  path->lateral_m = combined.value;
  path->lateral_sigma_m = combined.sigma;
}

void Localizer::ReleaseUnusedKeyImages() {
  std::vector<NodeData*> cached;
  for (auto& [id, node] : nodes_) {
    if (node->HasDerivedData()) cached.push_back(node.get());
  }
  const size_t capacity = static_cast<size_t>(options_.max_cached_key_images);
  if (cached.size() <= capacity) return;
  // The most recently used first (ties by node id, so that runs are repeatable).
  std::sort(cached.begin(), cached.end(), [](const NodeData* a, const NodeData* b) {
    return a->last_used != b->last_used ? a->last_used > b->last_used : a->node->id < b->node->id;
  });
  for (size_t i = capacity; i < cached.size(); ++i) cached[i]->ReleaseDerivedData();
}

int Localizer::NumCachedKeyImages() const {
  return static_cast<int>(std::count_if(nodes_.begin(), nodes_.end(),
                                        [](const auto& entry) { return entry.second->HasDerivedData(); }));
}

bool Localizer::IsNeighbour(arc_t arc, arc_t other) const {
  const auto& successors = belief_.Successors(arc);
  const auto& predecessors = belief_.Predecessors(arc);
  return std::find(successors.begin(), successors.end(), other) != successors.end() ||
         std::find(predecessors.begin(), predecessors.end(), other) != predecessors.end();
}

bool Localizer::MeetAtANode(arc_t arc, arc_t other) const {
  const ArcData* first = Arc(arc);
  const ArcData* second = Arc(other);
  return first != nullptr && second != nullptr &&
         (HasEnd(*second->arc, first->arc->from) || HasEnd(*second->arc, first->arc->to));
}

void Localizer::ReportTracking(arc_t arc_id, double along, double sigma, double confidence,
                               FrameResult* result) const {
  const ArcData* arc = Arc(arc_id);
  result->state = LocalizerState::kTracking;
  result->arc = arc_id;
  result->node_from = arc->arc->from;
  result->node_to = arc->arc->to;
  result->confidence = confidence;
  result->position_valid = true;
  result->position_on_arc = along;
  result->position_sigma = sigma;
}

std::optional<double> Localizer::AlongCurrentArc() const {
  const PlaceEstimate& estimate = belief_.estimate();
  if (arc_ == kInvalidArcId || estimate.arc == kInvalidArcId) return std::nullopt;
  if (estimate.arc == arc_) return estimate.along;
  const std::optional<double> distance =
      belief_.Distance({arc_, 0.0}, {estimate.arc, estimate.along}, options_.belief.reach);
  if (!distance) return std::nullopt;
  return *distance / belief_.ArcLength(arc_);
}

void Localizer::FillCounts(FrameResult* result) const {
  result->tracked = tracker_.NumFeatures();
  result->tracked_by_role = {0, 0, 0};
  const ArcData* arc = Arc(arc_);
  if (arc == nullptr) return;
  const ArcData* next = Arc(arc->next);
  for (const TrackedFeature& f : tracker_.Features()) {
    ArcRole role;
    if (arc->points.count(f.id)) {
      role = ArcRole::kCurrent;
    } else if (next != nullptr && next->points.count(f.id)) {
      role = ArcRole::kNext;
    } else {
      role = ArcRole::kPrevious;
    }
    ++result->tracked_by_role[static_cast<int>(role)];
    result->marks.push_back({f.warp.position, role, true});
  }
}

std::optional<Rigid3d> Localizer::GuessCurrentFrom(node_t node) const {
  if (const auto it = last_geometry_.find(node); it != last_geometry_.end()) return it->second;
  // A key-image not related to the previous frame (the one ahead after a transition): from the previous frame's
  // absolute pose in its arc's reconstruction, through the arc geometries and the relative scale at their node (the
  // guess only needs the translation's direction).
  if (!last_pose_) return std::nullopt;
  const ArcData* arc = Arc(last_pose_->arc);
  if (arc == nullptr) return std::nullopt;
  const Rigid3d& current_from_a = last_pose_->current_from_from;
  if (node == arc->arc->from) return current_from_a;
  Rigid3d current_from_b = current_from_a * arc->arc->to_from_from.Inverse();
  if (node == arc->arc->to) return current_from_b;
  const ArcData* next = Arc(arc->next);
  if (next == nullptr || node != next->arc->to) return std::nullopt;
  const std::optional<double> unit = UnitRatio(arc->arc->id, next->arc->id, +1);
  if (!unit) return std::nullopt;
  current_from_b.translation *= *unit;
  return current_from_b * next->arc->to_from_from.Inverse();
}

Localizer::CurrentGeometry Localizer::EstimateCurrentGeometry(node_t node_id) {
  CurrentGeometry current;
  current.node = node_id;
  const NodeData& node = Node(node_id);
  std::vector<Vector3d> bearings_key, bearings_current;
  for (const TrackedFeature& f : tracker_.Features()) {
    // Not the features the robust fallback located (LocalizerOptions::relocalization_robust_alignment): their windows
    // matched their references only in part, and a few such tracks bias a five-point geometry on a few more.
    if (f.robust_acquired) continue;
    const auto key = node.bearings.find(f.id);
    const auto now = bearings_.find(f.id);
    if (key == node.bearings.end() || now == bearings_.end()) continue;
    bearings_key.push_back(key->second);
    bearings_current.push_back(now->second);
    current.ids.push_back(f.id);
  }
  if (static_cast<int>(current.ids.size()) < geometry_options_.min_inliers) return current;
  current.estimated = true;
  // A guess from the previous frame (GuessCurrentFrom) is scored first: frame to frame the geometry changes little,
  // and the robust loop then stops after few samples.
  const std::optional<Rigid3d> guess = GuessCurrentFrom(node_id);
  current.geometry = EstimateRelativePose(bearings_key, bearings_current, camera_->FocalLength(), geometry_options_,
                                          guess ? &*guess : nullptr);
  if (current.geometry.success) {
    last_geometry_[node_id] = current.geometry.b_from_a;
  } else {
    last_geometry_.erase(node_id);
  }
  current.usable = GeometryUsable(current.geometry, max_sigma_p_px_);
  return current;
}

AbsolutePose Localizer::EstimatePoseInArc(const ArcData& arc, PoseSpread* spread, bool without_robust) const {
  std::vector<Vector3d> points, bearings;
  std::vector<Matrix3d> covariances;
  const Vector3d centre_b = CameraCentre(arc.arc->to_from_from);
  for (const TrackedFeature& f : tracker_.Features()) {
    if (without_robust && f.robust_acquired) continue;
    const auto point = arc.points.find(f.id);
    const auto bearing = bearings_.find(f.id);
    if (point == arc.points.end() || bearing == bearings_.end()) continue;
    points.push_back(point->second);
    bearings.push_back(bearing->second);
    // The arc's points were triangulated from its two key-images (teach), by the tracker that measures the bearings.
    if (options_.pose_point_uncertainty) covariances.push_back(TwoViewPointCovariance(point->second, centre_b));
  }
  AbsolutePose pose = EstimateAbsolutePose(points, bearings, camera_->FocalLength(), pose_options_,
                                           options_.pose_point_uncertainty ? &covariances : nullptr);
  if (spread != nullptr && pose.success) {
    *spread = SpreadOfInliers(pose, points, bearings, centre_b.norm(), camera_->FocalLength());
  }
  return pose;
}

namespace {

// Steps 1-3 of the decomposed point transfer for `arc` with a current geometry W_t:key (key = one of the arc's
// key-images): the shared features are the geometry's inliers that the arc reconstructs.
std::optional<PointTransfer> MakeTransfer(const MapArc& arc, const std::unordered_map<feature_t, Vector3d>& points,
                                          const TwoViewGeometry& geometry, const std::vector<feature_t>& ids,
                                          ArcImage key, double image_margin) {
  std::vector<Vector3d> arc_points, current_points;
  for (size_t i = 0; i < ids.size(); ++i) {
    if (!geometry.inlier_mask[i]) continue;
    const auto it = points.find(ids[i]);
    if (it == points.end()) continue;
    arc_points.push_back(it->second);
    current_points.push_back(geometry.points_in_a[i]);
  }
  PointTransferOptions options;
  options.image_margin_px = image_margin;
  PointTransfer transfer =
      PointTransfer::Create(arc.to_from_from, geometry.b_from_a, key, arc_points, current_points, options);
  if (!transfer.valid()) return std::nullopt;
  return transfer;
}

}  // namespace

TransferredPoint ArcPredictor::Transfer(const Vector3d& point_in_a, const CameraModel& camera, ArcImage reference,
                                        double margin) const {
  TransferredPoint result;
  const Vector3d in_current = current_from_a * point_in_a;
  const Vector3d in_reference = reference == ArcImage::kA ? point_in_a : b_from_a * point_in_a;
  const double reference_distance = in_reference.norm();
  result.distance_ratio = reference_distance > 0.0 ? in_current.norm() / reference_distance : 0.0;
  result.projectable = camera.Project(in_current, &result.pixel) && result.pixel.allFinite();
  result.in_image = result.projectable && camera.InImage(result.pixel, margin);
  return result;
}

namespace {

std::optional<ArcPredictor> FromTransfer(const std::optional<PointTransfer>& transfer) {
  if (!transfer) return std::nullopt;
  return ArcPredictor{transfer->current_from_a(), transfer->arc_b_from_a()};
}

}  // namespace

Localizer::LaneEntry Localizer::LaneEntryOf(arc_t arc, double along, const PoseDeviation& lateral,
                                            double heading) const {
  const double length = belief_.ArcLength(arc);
  return {GraphPlace{arc, along}, lateral.deviation * length, lateral.sigma * length, heading};
}

PlaceMeasurement Localizer::PlacePose(const ArcData& arc, const ArcPosition& placed, const AbsolutePose& pose,
                                      const PoseSpread& spread, std::optional<LaneEntry>* lane) const {
  const Rigid3d& b_from_a = arc.arc->to_from_from;
  const PoseDeviation lateral = LateralOffArc(pose, b_from_a);
  const LaneCheck lane_check = CheckLane(arc.arc->id, placed.along, lateral);
  const double collapsed = CollapseProbability(lane_check, options_.placement);
  lane->reset();
  if (lateral.valid && collapsed < 0.5) {
    *lane = LaneEntryOf(arc.arc->id, placed.along, lateral, HeadingOffArc(pose.cam_from_world, b_from_a, placed.along));
  }
  return PoseMeasurement(arc.arc->id, placed, pose, b_from_a, options_.placement, arc.bounds, spread,
                         HeightOffArc(pose, b_from_a), collapsed, FarSideProbability(lane_check, options_.placement));
}

LaneCheck Localizer::CheckLane(arc_t arc, double along, const PoseDeviation& lateral) const {
  const PlacementModel& model = options_.placement;
  if (!lateral.valid || !(model.pose_lateral_sigma > 0)) return {};
  const double length = belief_.ArcLength(arc);
  std::vector<LaneObservation> observations;
  for (const LaneEntry& entry : lane_) {
    // The poses within `lane_window` arc lengths of travel (none across a jump out of the belief's reach).
    const std::optional<double> travelled = belief_.Distance(entry.place, GraphPlace{arc, along}, model.lane_max_arcs);
    if (!travelled || *travelled < -model.lane_window * length || *travelled > model.lane_window * length) continue;
    observations.push_back({entry.lateral, entry.sigma, *travelled, entry.heading});
  }
  const PoseDeviation prediction = LanePrediction(observations, length, model);
  if (!prediction.valid || !(length > 0)) return {};
  return {true, lateral.deviation, prediction.deviation / length, std::hypot(lateral.sigma, prediction.sigma / length)};
}

ArcPosition Localizer::UpdateBelief(const Placements& placements) {
  // One placement from the tracked features per frame (they are not independent evidence, belief.h): the absolute
  // pose, else the current geometry with the lower σ_p, else the placement in a neighbouring arc; plus the key-image
  // a bootstrap verified in this frame. (A pose whose lateral offset refuted it giving way to the current geometries
  // was measured and not kept: README, "The camera keeps to its lane".)
  std::vector<PlaceMeasurement> measurements;
  if (placements.pose) {
    measurements.push_back(*placements.pose);
  } else if (placements.from && (!placements.to || placements.sigma_p_from <= placements.sigma_p_to)) {
    measurements.push_back(*placements.from);
  } else if (placements.to) {
    measurements.push_back(*placements.to);
  } else if (placements.neighbour) {
    measurements.push_back(*placements.neighbour);
  }
  if (bootstrap_key_image_) {
    // Beside the path the verified key-image is a looser measurement (PlacementModel::key_image_beside_sigma): the
    // camera's distance from the path by this frame's pose, else by the lane's last pose, the larger when both.
    const auto beside_of = [this](const LaneEntry& entry) {
      const double length = belief_.ArcLength(entry.place.arc);
      return length > 0 ? std::abs(entry.lateral) / length : 0.0;
    };
    double beside = 0.0;
    if (placements.lane) beside = beside_of(*placements.lane);
    if (!lane_.empty()) beside = std::max(beside, beside_of(lane_.back()));
    measurements.push_back(KeyImageMeasurement(*Arc(bootstrap_key_image_->arc)->arc, bootstrap_key_image_->node,
                                               bootstrap_key_image_->candidates, options_.placement, beside));
    bootstrap_key_image_.reset();
  }
  // The frame's own placement for the gap rule (Localize): of the last update when it has two (tracks given up and
  // relocalized).
  if (!measurements.empty()) frame_placement_ = measurements.front();
  const std::vector<double> inlier = belief_.Update(measurements, frame_counter_);
  belief_updated_ = true;
  // The lane keeps the poses the belief took as right (PlacementModel::pose_lateral_sigma). A lane entry comes with
  // the pose that is this frame's first measurement (the current arc's, else the neighbour's: Placements::lane).
  if (placements.lane && !inlier.empty() && inlier[0] >= 0.5) {
    lane_.push_back(*placements.lane);
    if (lane_.size() > static_cast<size_t>(options_.placement.lane_max_poses)) lane_.erase(lane_.begin());
  }
  const std::optional<double> along = AlongCurrentArc();
  return along ? AlongArc(*along) : ArcPosition();
}

void Localizer::Localize(FrameResult* result) {
  const ArcData* arc = Arc(arc_);
  const ArcData* previous = Arc(arc->previous);
  const ArcData* next = Arc(arc->next);
  const node_t a = arc->arc->from;
  const node_t b = arc->arc->to;

  bearings_.clear();
  for (const TrackedFeature& f : tracker_.Features()) {
    Vector3d bearing;
    if (camera_->Unproject(f.warp.position, &bearing)) bearings_[f.id] = bearing;
  }
  const CurrentGeometry geometry_a = EstimateCurrentGeometry(a);
  const CurrentGeometry geometry_b = EstimateCurrentGeometry(b);
  if (geometry_a.geometry.success) result->sigma_p_from = geometry_a.geometry.sigma_p;
  if (geometry_b.geometry.success) result->sigma_p_to = geometry_b.geometry.sigma_p;

  const double margin = tracker_.Options().alignment.window_size / 2 + 2;
  // Transfers through usable geometries only (σ_p gating, Segvic 2009 §5.2.1).
  std::optional<PointTransfer> transfer_a, transfer_b, transfer_next, transfer_previous;
  if (geometry_a.usable) {
    transfer_a = MakeTransfer(*arc->arc, arc->points, geometry_a.geometry, geometry_a.ids, ArcImage::kA, margin);
    if (previous != nullptr) {
      transfer_previous = MakeTransfer(*previous->arc, previous->points, geometry_a.geometry, geometry_a.ids,
                                       ArcImage::kB, margin);
    }
  }
  if (geometry_b.usable) {
    transfer_b = MakeTransfer(*arc->arc, arc->points, geometry_b.geometry, geometry_b.ids, ArcImage::kB, margin);
    if (next != nullptr) {
      transfer_next =
          MakeTransfer(*next->arc, next->points, geometry_b.geometry, geometry_b.ids, ArcImage::kA, margin);
    }
  }
  // The camera placed on the arc through each current geometry ...
  Placements placements;
  ArcPosition position_a, position_b;
  if (transfer_a) position_a = LocateOnArc(transfer_a->current_from_a(), arc->arc->to_from_from, arc->bounds);
  if (transfer_b) position_b = LocateOnArc(transfer_b->current_from_a(), arc->arc->to_from_from, arc->bounds);
  if (position_a.valid) {
    result->position_via_from = position_a.along;
    placements.from = GeometryMeasurement(arc_, position_a, ArcImage::kA, options_.placement);
    placements.sigma_p_from = geometry_a.geometry.sigma_p;
  }
  if (position_b.valid) {
    result->position_via_to = position_b.along;
    placements.to = GeometryMeasurement(arc_, position_b, ArcImage::kB, options_.placement);
    placements.sigma_p_to = geometry_b.geometry.sigma_p;
  }
  // ... and by its absolute pose in the arc's reconstruction (σ_p gated like the current geometries).
  if (options_.place_by_absolute_pose) {
    PoseSpread spread;
    const AbsolutePose pose = EstimatePoseInArc(*arc, &spread);
    // The camera's place in metres (LastPose: the offset the path law steers by, the next frame's guess) rests on the
    // features the paper's warp located only: the robust fallback's are off by a few tenths of a pixel and, taken by
    // the pose, swerved a closed loop (LocalizerOptions::relocalization_robust_alignment).
    const bool robust_tracked = options_.relocalization_robust_alignment && tracker_.NumRobustFeatures() > 0;
    const AbsolutePose metric_pose = robust_tracked ? EstimatePoseInArc(*arc, nullptr, /*without_robust=*/true) : pose;
    last_pose_.reset();
    if (metric_pose.success) {
      last_pose_ = LastPose{arc_,
                            metric_pose.cam_from_world,
                            frame_counter_,
                            metric_pose.sigma_p < max_sigma_p_px_,
                            metric_pose.covariance_valid
                                ? std::optional<PoseCovariance>(PoseCovariance{metric_pose.centre_covariance,
                                                                               metric_pose.rotation_covariance,
                                                                               metric_pose.rotation_centre_covariance})
                                : std::nullopt,
                            NoiseFloorFactor(metric_pose, options_.lateral_noise_floor_px * pixel_scale_)};
    }
    if (pose.success) {
      result->sigma_p_pose = pose.sigma_p;
      result->pose_inliers = pose.num_inliers;
      const ArcPosition position_pose = LocateOnArc(pose.cam_from_world, arc->arc->to_from_from, arc->bounds);
      if (position_pose.valid) result->position_via_pose = position_pose.along;
      if (position_pose.valid && pose.sigma_p < max_sigma_p_px_) {
        placements.pose = PlacePose(*arc, position_pose, pose, spread, &placements.lane);
      }
    }
  }
  // No placement on the current arc (its tracked features do not fix the camera: a few, distant, or reconstructed
  // by none of W_t:a / W_t:b's inliers): the camera placed in a neighbouring arc's frame instead — by its absolute
  // pose in that arc's reconstruction, else through the decomposed transfer of W_t:a (previous arc) / W_t:b (next).
  if (!placements.pose && !placements.from && !placements.to) {
    int best_inliers = 0;
    for (const ArcData* neighbour : {next, previous}) {
      if (neighbour == nullptr || !options_.place_by_absolute_pose) continue;
      PoseSpread spread;
      const AbsolutePose pose = EstimatePoseInArc(*neighbour, &spread);
      if (!pose.success || !(pose.sigma_p < max_sigma_p_px_) || pose.num_inliers <= best_inliers) continue;
      const ArcPosition placed = LocateOnArc(pose.cam_from_world, neighbour->arc->to_from_from, neighbour->bounds);
      if (!placed.valid) continue;
      best_inliers = pose.num_inliers;
      placements.neighbour = PlacePose(*neighbour, placed, pose, spread, &placements.lane);
    }
    if (!placements.neighbour) {
      // W_t:b relates the camera to the next arc's first key-image, W_t:a to the previous arc's second.
      for (const auto& [neighbour, transfer, key] :
           {std::tuple{next, &transfer_next, ArcImage::kA}, std::tuple{previous, &transfer_previous, ArcImage::kB}}) {
        if (neighbour == nullptr || !transfer->has_value()) continue;
        const ArcPosition placed =
            LocateOnArc((*transfer)->current_from_a(), neighbour->arc->to_from_from, neighbour->bounds);
        if (!placed.valid) continue;
        placements.neighbour = GeometryMeasurement(neighbour->arc->id, placed, key, options_.placement);
        break;
      }
    }
  }
  // Where the camera is: the belief, updated with this frame's placements, on the current arc.
  const ArcPosition position = UpdateBelief(placements);
  const PlaceEstimate& estimate = belief_.estimate();

  // The three-view geometry of the current arc: W_k adjusted to the more accurate current geometry whose placement
  // agrees with the belief (within `agreement_sigmas` standard deviations of the placement and the belief). A
  // decomposed transfer whose scale or translation direction is off predicts every feature of the arc somewhere
  // else.
  const double belief_sigma = estimate.sigma * belief_.ArcLength(estimate.arc) / belief_.ArcLength(arc_);
  const auto agrees = [&](const std::optional<PlaceMeasurement>& placed) {
    if (!placed) return false;
    if (!position.valid || !estimate.evidence) return true;  // nothing reliable to check against
    return std::abs(placed->along - position.along) <=
           options_.agreement_sigmas * std::hypot(placed->sigma, belief_sigma);
  };
  const bool believe_a = transfer_a && agrees(placements.from);
  const bool believe_b = transfer_b && agrees(placements.to);
  std::optional<PointTransfer> transfer_current;
  if (believe_a && (!believe_b || geometry_a.geometry.sigma_p <= geometry_b.geometry.sigma_p)) {
    transfer_current = transfer_a;
    result->sigma_p = geometry_a.geometry.sigma_p;
  } else if (believe_b) {
    transfer_current = transfer_b;
    result->sigma_p = geometry_b.geometry.sigma_p;
  }

  std::optional<ArcPredictor> predict_current = FromTransfer(transfer_current);
  std::optional<ArcPredictor> predict_next = FromTransfer(transfer_next);
  std::optional<ArcPredictor> predict_previous = FromTransfer(transfer_previous);
  // Neighbouring arcs that share too few features with the current geometries: chain the current arc's pose through
  // the relative scale stored at the common node (a length in units of the arc leaving the node times the scale is
  // the same length in units of the arc entering it, design §1).
  if (predict_current && !predict_next && next != nullptr) {
    if (const std::optional<double> s = map_.ScaleAt(b, arc->arc->id, next->arc->id); s && *s > 0) {
      Rigid3d current_from_b = predict_current->current_from_a * arc->arc->to_from_from.Inverse();
      current_from_b.translation /= *s;
      predict_next = ArcPredictor{current_from_b, next->arc->to_from_from};
    }
  }
  if (predict_current && !predict_previous && previous != nullptr) {
    if (const std::optional<double> s = map_.ScaleAt(a, previous->arc->id, arc->arc->id); s && *s > 0) {
      Rigid3d a_from_z = previous->arc->to_from_from;
      a_from_z.translation /= *s;  // previous arc's unit -> current arc's unit
      Rigid3d current_from_z = predict_current->current_from_a * a_from_z;
      current_from_z.translation *= *s;  // back to the previous arc's unit
      predict_previous = ArcPredictor{current_from_z, previous->arc->to_from_from};
    }
  }

  // Consistency (Segvic 2009 §5.2.1): discontinue tracks that drifted from their prediction.
  std::array<RolePredictor, 3> roles = {RolePredictor{arc, &predict_current, ArcRole::kCurrent},
                                        RolePredictor{next, &predict_next, ArcRole::kNext},
                                        RolePredictor{previous, &predict_previous, ArcRole::kPrevious}};
  const double drift_limit =
      std::max(options_.max_drift_px * pixel_scale_, 3.0 * std::max(0.0, result->sigma_p));
  // Sanity check of each transfer first: when many of an arc's tracked features disagree with their predictions, the
  // transfer is wrong (e.g. a weakly conditioned current geometry right after passing a key-image), not the tracks;
  // that arc then gets neither consistency checks nor predictions in this frame.
  static const std::optional<ArcPredictor> kNoPredictor;
  std::vector<feature_t> drifted;
  for (RolePredictor& r : roles) {
    if (r.arc == nullptr || !r.transfer->has_value()) continue;
    int checked = 0;
    std::vector<feature_t> candidates;
    for (const TrackedFeature& f : tracker_.Features()) {
      const auto point = r.arc->points.find(f.id);
      if (point == r.arc->points.end()) continue;
      bool owned_by_earlier_role = false;
      for (const RolePredictor& other : roles) {
        if (&other == &r) break;
        owned_by_earlier_role |= other.arc != nullptr && other.arc->points.count(f.id) > 0;
      }
      if (owned_by_earlier_role) continue;
      const TransferredPoint predicted = (*r.transfer)->Transfer(point->second, *camera_, ArcImage::kA, 0.0);
      if (!predicted.projectable) continue;
      ++checked;
      if ((predicted.pixel - f.warp.position).norm() > drift_limit) candidates.push_back(f.id);
    }
    if (static_cast<double>(candidates.size()) > std::max(3.0, options_.max_drift_fraction * checked)) {
      r.transfer = &kNoPredictor;
      continue;
    }
    drifted.insert(drifted.end(), candidates.begin(), candidates.end());
  }
  for (const feature_t id : drifted) {
    tracker_.Remove(id);
    reference_node_.erase(id);
    ++result->dropped;
    ++result->drifted;
  }

  // Prudence (eqs. (7), (8)) and resumption of mapped but untracked features (resumption.cc).
  ResumePredicted(roles, position, result);
  // Without a transfer for the next arc (the current geometries share too few features with it and the map stores
  // no scale at b) or for the current arc (right after a transition), features seen in the nearby key-image are
  // predicted from the displacement of tracked neighbours seen there too: near that key-image the image motion is
  // locally coherent, and the acceptance test of RefinePrediction guards against wrong associations.
  const ResumptionPolicy policy = DecideResumption(position, options_.next_arc_ratio, options_.previous_arc_ratio);
  if (next != nullptr && !predict_next && policy.next) ResumeFromNeighbours(*next, b, ArcRole::kNext, result);
  if (!predict_current) ResumeFromNeighbours(*arc, last_passed_ == b ? b : a, ArcRole::kCurrent, result);

  // Steering (Segvic 2009, eq. (10), control/steering.h) over the current arc's features, towards key-image b.
  {
    const NodeData& node_b = Node(b);
    std::vector<SteeringFeature> features;
    for (const TrackedFeature& f : tracker_.Features()) {
      if (!arc->points.count(f.id)) continue;
      const auto target = node_b.bearings.find(f.id);
      Vector3d now;
      if (target == node_b.bearings.end() || !camera_->Unproject(f.warp.position, &now)) continue;
      features.push_back({now, target->second});
    }
    const SteeringCommand command =
        SteerByImage(features, options_.steering_gain, std::tan(options_.steering_half_field_deg * M_PI / 180.0));
    result->steering = command.angle;
    result->steering_valid = command.valid;
  }

  // Health of the tracks: enough features of the current arc and a trustworthy estimate from them (a usable current
  // geometry or absolute pose). After `max_bad_frames` bad frames in a row the tracks are given up and the frame is
  // re-initialised by wide-baseline matching; the belief carries on (it only loses this evidence).
  int current_tracked = 0;
  for (const TrackedFeature& f : tracker_.Features()) current_tracked += arc->points.count(f.id) ? 1 : 0;
  // The estimate must also be evidence the belief accepts: tracks whose placements the belief keeps explaining as
  // outliers (the camera placed off the map, past the end of a piece of it, or far from every place the motion
  // allows) are no better than none, and relocalization may find what they cannot.
  const bool good = current_tracked >= options_.min_features &&
                    (geometry_a.usable || geometry_b.usable || placements.pose.has_value()) &&
                    estimate.evidence;
  // (A placement in a neighbouring arc keeps the belief informed but does not make the current arc's tracks good.)
  bad_frames_ = good ? 0 : bad_frames_ + 1;
  // Too few features of the current arc and no evidence from any placement: these tracks cannot recover by
  // themselves (resumption needs a placement to predict from), so they are given up at once; a frame whose
  // features are there but whose geometries are momentarily unusable gets `max_bad_frames` frames.
  const bool hopeless = current_tracked < options_.min_features && !estimate.evidence;
  if (hopeless || bad_frames_ >= options_.max_bad_frames) {
    spdlog::debug("repeat: tracks given up at frame {} ({} features of arc {}, W_t:a {}, W_t:b {}, pose {})",
                  result->frame_index, current_tracked, arc_, geometry_a.usable, geometry_b.usable,
                  placements.pose.has_value());
    state_ = LocalizerState::kLost;
    ClearTracks();
    last_arc_ = arc_;
    lost_at_frame_ = frame_counter_;
    arc_ = kInvalidArcId;
    return;
  }

  // Topological transition (Segvic 2009 §5.2.2, eq. (9)) on the belief: the tracked location moves to the arc that
  // holds the belief's mode — forward when the mode has passed the plane through b (along > 1), backward when it
  // lies more than `backward_margin` behind a — possibly over several arcs in one frame. Only in a frame with
  // evidence: a prediction alone moves the belief but not the tracks, whose features are the evidence to come.
  if (!estimate.evidence || !position.valid) return;
  int direction = DecideTransition(position, options_.backward_margin);
  if (direction == 0) return;
  const std::vector<arc_t> path = PathTo(estimate.arc, direction);
  // Across a gap in the map the belief's graph is a guess (the gap as long as the teach drive took to cross it), so
  // the tracks follow the belief there only when this frame's own placement puts the camera on the belief's arc as
  // surely as the belief must be (PlaceBelief::MeasurementSupport). Otherwise a belief that lagged on the piece
  // before took tracks just located on the next piece back across the gap, two arcs from the truth
  // (`scripts/validation --random 24`'s rand1114 frame 219 with `--multi-view-points`).
  arc_t from = arc_;
  for (const arc_t step : path) {
    if (!MeetAtANode(from, step) &&
        (!frame_placement_ ||
         belief_.MeasurementSupport(estimate.arc, *frame_placement_) < options_.belief.min_confidence)) {
      spdlog::debug("repeat: frame {}: no transition to arc {} across a gap without this frame's support",
                    result->frame_index, estimate.arc);
      return;
    }
    from = step;
  }
  for (const arc_t step : path) {
    ApplyTransition(step, direction, result);
    result->transition += direction;
  }
}

std::vector<arc_t> Localizer::PathTo(arc_t target, int direction) const {
  // Breadth first from the current arc along successors (forward) or predecessors (backward), within the belief's
  // reach.
  std::vector<std::vector<arc_t>> frontier{{arc_}};
  for (int hop = 0; hop < options_.belief.reach; ++hop) {
    std::vector<std::vector<arc_t>> next;
    for (const std::vector<arc_t>& path : frontier) {
      const arc_t last = path.back();
      for (const arc_t step : direction > 0 ? belief_.Successors(last) : belief_.Predecessors(last)) {
        std::vector<arc_t> longer = path;
        longer.push_back(step);
        if (step == target) return std::vector<arc_t>(longer.begin() + 1, longer.end());
        next.push_back(std::move(longer));
      }
    }
    frontier.swap(next);
  }
  return {};
}

std::optional<double> Localizer::UnitRatio(arc_t old_arc, arc_t new_arc, int direction) const {
  // Design §1: a length in units of the arc leaving a node times the stored scale is the same length in units of
  // the arc entering it.
  const ArcData* old_data = Arc(old_arc);
  const std::optional<double> scale = direction > 0 ? map_.ScaleAt(old_data->arc->to, old_arc, new_arc)
                                                    : map_.ScaleAt(old_data->arc->from, new_arc, old_arc);
  if (!scale || !(*scale > 0)) return std::nullopt;
  return direction > 0 ? 1.0 / *scale : *scale;
}

void Localizer::ApplyTransition(arc_t target, int direction, FrameResult* result) {
  const ArcData* left = Arc(arc_);
  arc_ = target;
  const ArcData* arc = Arc(arc_);
  const ArcData* previous = Arc(arc->previous);
  const ArcData* next = Arc(arc->next);
  // The key-image just passed, where the camera is now.
  last_passed_ = direction > 0 ? arc->arc->from : arc->arc->to;
  spdlog::debug("repeat: frame {}: {} transition to arc {} ({} -> {})", result->frame_index,
                direction > 0 ? "forward" : "backward", arc_, arc->arc->from, arc->arc->to);

  // Features of no arc around the new location are dropped (Segvic 2009 §5.2.2).
  for (const TrackedFeature& f : std::vector<TrackedFeature>(tracker_.Features())) {
    bool kept = false;
    for (const ArcData* candidate : {arc, next, previous, left}) {
      kept |= candidate != nullptr && candidate->points.count(f.id);
    }
    if (!kept) {
      tracker_.Remove(f.id);
      reference_node_.erase(f.id);
      ++result->dropped;
    }
  }
  retry_after_.clear();
  if (!options_.redefine_references) return;
  // References are redefined (§5.2.2): the new current arc's features take theirs from the key-image the camera
  // now approaches, those of the arc just left from the key-image just passed.
  const node_t approached = direction > 0 ? arc->arc->to : arc->arc->from;
  RedefineReferences(*arc, approached, result);
  RedefineReferences(*left, last_passed_, result);
}

}  // namespace retrace
