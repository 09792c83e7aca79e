#include "retrace/repeat/localizer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include <Eigen/SVD>
#include <spdlog/spdlog.h>

#include "retrace/geometry/absolute_pose.h"
#include "retrace/geometry/relative_pose.h"
#include "retrace/util/error.h"

namespace retrace {
namespace {

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + mid, values.end());
  return values[mid];
}

Vector3d CameraCentre(const Rigid3d& cam_from_world) {
  return -cam_from_world.rotation.transpose() * cam_from_world.translation;
}

// Where the last accepted position and the camera's speed along the arc put it in frame `frame`.
double ExpectedAlong(const ArcProgress& last, size_t frame) {
  const double frames = frame > last.frame ? static_cast<double>(frame - last.frame) : 0.0;
  return last.along + (last.speed_known ? last.speed : 0.0) * frames;
}

}  // namespace

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
  if (!(position_agreement >= 0) || !(transfer_agreement > 0)) return fail("agreement tolerances must be positive");
  if (!(stale_margin >= 0)) return fail("stale_margin must be >= 0");
  if (!(max_progress_step > 0) || !(progress_tolerance > 0)) {
    return fail("max_progress_step and progress_tolerance must be > 0");
  }
  if (retry_interval < 1) return fail("retry_interval must be >= 1");
  if (min_features < 8) return fail("min_features must be >= 8");
  if (max_bad_frames < 1) return fail("max_bad_frames must be >= 1");
  if (min_bootstrap_inliers < 8 || min_bootstrap_features < 8) return fail("bootstrap minima must be >= 8");
  if (prediction_skipped_levels < 0) return fail("prediction_skipped_levels must be >= 0");
  if (relocalization_neighbourhood < 0 || relocalization_widening < 0) {
    return fail("relocalization_neighbourhood and relocalization_widening must be >= 0");
  }
  if (global_relocalization_frames < 1) return fail("global_relocalization_frames must be >= 1");
  if (retrieval_shortlist < 0 || retrieval_confident_inliers < 0) {
    return fail("retrieval_shortlist and retrieval_confident_inliers must be >= 0");
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
  return true;
}

ArcPosition LocateOnArc(const Rigid3d& current_from_a, const Rigid3d& arc_b_from_a) {
  ArcPosition position;
  const Vector3d c_t = CameraCentre(current_from_a);
  const Vector3d c_b = CameraCentre(arc_b_from_a);
  const double length_sq = c_b.squaredNorm();
  if (!c_t.allFinite() || !(length_sq > 0)) return position;
  position.valid = true;
  position.along = c_t.dot(c_b) / length_sq;
  const double length = std::sqrt(length_sq);
  position.distance_to_from = c_t.norm() / length;
  position.distance_to_to = (c_t - c_b).norm() / length;
  return position;
}

ResumptionPolicy DecideResumption(const ArcPosition& position, double next_arc_ratio, double previous_arc_ratio) {
  ResumptionPolicy policy;
  if (!position.valid) return policy;
  policy.next = position.distance_to_to < next_arc_ratio;              // Segvic 2009, eq. (7)
  policy.previous = position.distance_to_from < previous_arc_ratio;    // Segvic 2009, eq. (8)
  return policy;
}

bool GeometryUsable(const TwoViewGeometry& geometry, double max_sigma_p_px) {
  return geometry.success && geometry.sigma_p < max_sigma_p_px;
}

int DecideTransition(const ArcPosition& position, double backward_margin) {
  if (!position.valid) return 0;
  // Segvic 2009, eq. (9). With the camera centre C_t in the arc's frame (a at the origin, b at C_b), the plane
  // through C_b perpendicular to the direction of travel C_b - C_a is passed when (C_t - C_b) . C_b > 0, i.e.
  // along = C_t . C_b / |C_b|^2 > 1.
  if (position.along > 1.0) return +1;
  if (position.along < -backward_margin) return -1;
  return 0;
}

struct Localizer::NodeData {
  const MapNode* node = nullptr;
  std::unordered_map<feature_t, Vector2d> positions;
  std::unordered_map<feature_t, Vector3d> bearings;
  std::unique_ptr<ImagePyramid> pyramid;
  std::optional<WideBaselineFeatures> wide_baseline;
  std::optional<GlobalDescriptor> appearance;
  std::unordered_map<feature_t, std::unique_ptr<ReferencePatch>> references;  // null = cannot be cut
};

struct Localizer::ArcData {
  const MapArc* arc = nullptr;
  std::unordered_map<feature_t, Vector3d> points;
  arc_t previous = kInvalidArcId;
  arc_t next = kInvalidArcId;
};

struct Localizer::CurrentGeometry {
  node_t node = kInvalidNodeId;
  bool estimated = false;
  TwoViewGeometry geometry;       // key_from... : a = key-image, b = current image
  std::vector<feature_t> ids;     // feature of each correspondence
  bool usable = false;
};

Localizer::Localizer(const Map& map, const CameraModel& camera, const LocalizerOptions& options)
    : camera_(camera.Clone()), options_(options), map_(map) {
  std::string error;
  if (!options_.Check(&error)) throw std::invalid_argument("LocalizerOptions: " + error);
  pixel_scale_ = static_cast<double>(camera.width()) / options_.reference_width;
  max_sigma_p_px_ = options_.max_sigma_p_px * pixel_scale_;
  pyramid_options_ = TrackingPyramidOptions(camera.width(), options_.reference_width, options_.smoothing_sigma_px);
  geometry_options_ = options_.geometry;
  geometry_options_.ransac.max_error_px = options_.inlier_threshold_px * pixel_scale_;
  geometry_options_.min_parallax_px = options_.min_parallax_px * pixel_scale_;
  pose_options_ = options_.pose;
  pose_options_.ransac.max_error_px = options_.inlier_threshold_px * pixel_scale_;
  FeatureTrackerOptions tracker_options = options_.tracker;
  tracker_options.alignment.max_residual = options_.max_residual;
  tracker_options.num_levels = pyramid_options_.num_levels;
  tracker_ = FeatureTracker(tracker_options);
  refine_options_.alignment = options_.tracker.alignment;
  refine_options_.alignment.max_residual = options_.max_residual;
  refine_options_.alignment.scale_prior_sigma = 0.0;
  refine_options_.max_distance = options_.prediction_radius_px * pixel_scale_;
  refine_options_.max_scale_ratio = options_.prediction_scale_ratio;

  for (const MapNode& node : map_.nodes()) {
    if (node.image.empty()) throw InputError("map", "key-image " + std::to_string(node.id) + " is not loaded");
    if (node.image.cols != camera.width() || node.image.rows != camera.height()) {
      throw InputError("map", "key-image " + std::to_string(node.id) + " is " + std::to_string(node.image.cols) +
                                  "x" + std::to_string(node.image.rows) + " but the camera is " +
                                  std::to_string(camera.width()) + "x" + std::to_string(camera.height()));
    }
    auto data = std::make_unique<NodeData>();
    data->node = &node;
    for (const FeatureObservation& f : node.features) {
      Vector3d bearing;
      if (!camera_->Unproject(f.position, &bearing)) continue;
      data->positions[f.feature_id] = f.position;
      data->bearings[f.feature_id] = bearing;
    }
    nodes_[node.id] = std::move(data);
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
    arcs_[arc.id] = std::move(data);
  }
}

Localizer::~Localizer() = default;

void Localizer::SetStartArc(arc_t arc) {
  if (Arc(arc) == nullptr) throw InputError("start arc", "the map has no arc " + std::to_string(arc));
  start_arc_ = arc;
}

Localizer::NodeData& Localizer::Node(node_t id) { return *nodes_.at(id); }

const Localizer::ArcData* Localizer::Arc(arc_t id) const {
  const auto it = arcs_.find(id);
  return it == arcs_.end() ? nullptr : it->second.get();
}

const ImagePyramid& Localizer::NodePyramid(node_t id) {
  NodeData& node = Node(id);
  if (!node.pyramid) node.pyramid = std::make_unique<ImagePyramid>(node.node->image, pyramid_options_);
  return *node.pyramid;
}

const WideBaselineFeatures& Localizer::NodeWideBaseline(node_t id) {
  NodeData& node = Node(id);
  if (!node.wide_baseline) node.wide_baseline = ExtractWideBaselineFeatures(node.node->image, options_.matching);
  return *node.wide_baseline;
}

const ReferencePatch* Localizer::Reference(node_t node_id, feature_t feature) {
  NodeData& node = Node(node_id);
  auto it = node.references.find(feature);
  if (it == node.references.end()) {
    std::unique_ptr<ReferencePatch> patch;
    const auto position = node.positions.find(feature);
    if (position != node.positions.end()) {
      patch = std::make_unique<ReferencePatch>();
      if (!patch->Create(NodePyramid(node_id), position->second, tracker_.Options().alignment.window_size,
                         tracker_.Options().num_levels)) {
        patch.reset();
      }
    }
    it = node.references.emplace(feature, std::move(patch)).first;
  }
  return it->second.get();
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
  stale_ = false;
  if (state_ == LocalizerState::kLost) state_ = LocalizerState::kRelocalizing;
  FrameResult result;
  result.frame_index = frame.index;
  pyramid_.Build(frame.image, pyramid_options_);
  prediction_pyramid_ = pyramid_.FinestLevels(pyramid_.NumLevels() - options_.prediction_skipped_levels);

  if (state_ == LocalizerState::kTracking) {
    const int before = tracker_.NumFeatures();
    tracker_.Track(pyramid_);
    result.dropped += before - tracker_.NumFeatures();
    for (auto it = reference_node_.begin(); it != reference_node_.end();) {
      it = tracker_.Find(it->first) == nullptr ? reference_node_.erase(it) : std::next(it);
    }
    Localize(&result);
  }
  // Not localized (before, or lost in this very frame): re-initialise from this frame, so that a loss costs no
  // extra frame. A frame that lost track and could not be re-initialised is reported `lost`, the following ones
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

  if (state_ == LocalizerState::kTracking && stale_) {
    result.state = LocalizerState::kLost;
    result.position_valid = false;
    result.steering_valid = false;
    result.steering = 0.0;
  } else if (state_ == LocalizerState::kTracking) {
    const ArcData* arc = Arc(arc_);
    result.state = LocalizerState::kTracking;
    result.arc = arc_;
    result.node_from = arc->arc->from;
    result.node_to = arc->arc->to;
  } else {
    result.state = state_;
    result.position_valid = false;
    result.steering_valid = false;
    result.steering = 0.0;
  }
  FillCounts(&result);
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
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

AbsolutePose Localizer::EstimatePoseInArc(const ArcData& arc) const {
  std::vector<Vector3d> points, bearings;
  for (const TrackedFeature& f : tracker_.Features()) {
    const auto point = arc.points.find(f.id);
    const auto bearing = bearings_.find(f.id);
    if (point == arc.points.end() || bearing == bearings_.end()) continue;
    points.push_back(point->second);
    bearings.push_back(bearing->second);
  }
  return EstimateAbsolutePose(points, bearings, camera_->FocalLength(), pose_options_);
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

// The current camera in an arc's frame and scale, from which the arc's points are predicted (step 4 of the
// decomposed point transfer). Built from a PointTransfer, or chained to a neighbouring arc through the relative scale
// stored at their common node when the current geometry shares too few features with that arc.
struct ArcPredictor {
  Rigid3d current_from_a;  // arc frame and scale
  Rigid3d b_from_a;        // the arc's geometry (|t| = 1)

  TransferredPoint Transfer(const Vector3d& point_in_a, const CameraModel& camera, ArcImage reference,
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
};

namespace {

std::optional<ArcPredictor> FromTransfer(const std::optional<PointTransfer>& transfer) {
  if (!transfer) return std::nullopt;
  return ArcPredictor{transfer->current_from_a(), transfer->arc_b_from_a()};
}

}  // namespace

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
  // The camera on the arc through each current geometry.
  ArcPosition position_a, position_b;
  if (transfer_a) position_a = LocateOnArc(transfer_a->current_from_a(), arc->arc->to_from_from);
  if (transfer_b) position_b = LocateOnArc(transfer_b->current_from_a(), arc->arc->to_from_from);
  if (position_a.valid) result->position_via_from = position_a.along;
  if (position_b.valid) result->position_via_to = position_b.along;
  // ... and through its absolute pose in the arc's reconstruction (σ_p gated like the current geometries).
  std::optional<PlacedCamera> via_pose;
  if (options_.place_by_absolute_pose) {
    const AbsolutePose pose = EstimatePoseInArc(*arc);
    last_pose_.reset();
    if (pose.success) {
      last_pose_ = LastPose{arc_, pose.cam_from_world};
      result->sigma_p_pose = pose.sigma_p;
      result->pose_inliers = pose.num_inliers;
      const ArcPosition position_pose = LocateOnArc(pose.cam_from_world, arc->arc->to_from_from);
      if (position_pose.valid) result->position_via_pose = position_pose.along;
      if (pose.sigma_p < max_sigma_p_px_) via_pose = PlacedCamera{position_pose, pose.sigma_p};
    }
  }
  // The placements fused (FuseArcPositions): the absolute pose when it is believed, else the motion decides between
  // the current geometries' placements.
  const auto placed = [](const ArcPosition& p, const CurrentGeometry& g) {
    return p.valid ? std::optional<PlacedCamera>(PlacedCamera{p, g.geometry.sigma_p}) : std::nullopt;
  };
  const FusedArcPosition fused =
      FuseArcPositions(progress_, frame_counter_, via_pose, placed(position_a, geometry_a),
                       placed(position_b, geometry_b),
                       ContinuityLimits{options_.max_progress_step, options_.progress_tolerance},
                       options_.position_agreement);
  const ArcPosition& position = fused.position;
  result->position_valid = position.valid;
  result->position_on_arc = position.along;

  // The three-view geometry of the current arc: W_k adjusted to the more accurate current geometry — of those whose
  // placement of the camera was believed: used for the fused position, or (when the absolute pose placed the
  // camera) within `transfer_agreement` of it. A decomposed transfer whose scale or translation direction is off
  // predicts every feature of the arc somewhere else.
  const auto agrees = [&](const ArcPosition& p) {
    return p.valid && std::abs(p.along - position.along) <= options_.transfer_agreement;
  };
  const bool believe_a = !position.valid || fused.via_from || (fused.via_pose && agrees(position_a));
  const bool believe_b = !position.valid || fused.via_to || (fused.via_pose && agrees(position_b));
  std::optional<PointTransfer> transfer_current;
  if (transfer_a && believe_a &&
      (!transfer_b || !believe_b || geometry_a.geometry.sigma_p <= geometry_b.geometry.sigma_p)) {
    transfer_current = transfer_a;
    result->sigma_p = geometry_a.geometry.sigma_p;
  } else if (transfer_b && believe_b) {
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
  struct RoleTransfer {
    const ArcData* arc;
    const std::optional<ArcPredictor>* transfer;
    ArcRole role;
  };
  std::array<RoleTransfer, 3> roles = {RoleTransfer{arc, &predict_current, ArcRole::kCurrent},
                                       RoleTransfer{next, &predict_next, ArcRole::kNext},
                                       RoleTransfer{previous, &predict_previous, ArcRole::kPrevious}};
  const double drift_limit =
      std::max(options_.max_drift_px * pixel_scale_, 3.0 * std::max(0.0, result->sigma_p));
  // Sanity check of each transfer first: when many of an arc's tracked features disagree with their predictions, the
  // transfer is wrong (e.g. a weakly conditioned current geometry right after passing a key-image), not the tracks;
  // that arc then gets neither consistency checks nor predictions in this frame.
  const std::optional<ArcPredictor> kNoPredictor;
  std::vector<feature_t> drifted;
  for (RoleTransfer& r : roles) {
    if (r.arc == nullptr || !r.transfer->has_value()) continue;
    int checked = 0;
    std::vector<feature_t> candidates;
    for (const TrackedFeature& f : tracker_.Features()) {
      const auto point = r.arc->points.find(f.id);
      if (point == r.arc->points.end()) continue;
      bool owned_by_earlier_role = false;
      for (const RoleTransfer& other : roles) {
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
  // Consistency (Segvic 2009 §5.2.1): discontinue tracks that drifted from their prediction.
  for (const feature_t id : drifted) {
    tracker_.Remove(id);
    reference_node_.erase(id);
    ++result->dropped;
    ++result->drifted;
  }

  // Prudence (eqs. (7), (8)) and resumption of mapped but untracked features.
  const ResumptionPolicy policy =
      DecideResumption(position, options_.next_arc_ratio, options_.previous_arc_ratio);
  // References are cut from the arc's key-image nearest to the camera (see LocalizerOptions / header).
  std::array<node_t, 3> near_node{};
  near_node[static_cast<int>(ArcRole::kCurrent)] = position.valid && position.along < 0.5 ? a : b;
  near_node[static_cast<int>(ArcRole::kNext)] = b;
  near_node[static_cast<int>(ArcRole::kPrevious)] = a;
  for (const RoleTransfer& r : roles) {
    if (r.arc == nullptr || !r.transfer->has_value()) continue;
    if (r.role == ArcRole::kNext && !policy.next) continue;
    if (r.role == ArcRole::kPrevious && !policy.previous) continue;
    const ArcPredictor& transfer = **r.transfer;
    for (const auto& [id, point] : r.arc->points) {
      if (tracker_.Find(id) != nullptr) continue;
      const auto retry = retry_after_.find(id);
      if (retry != retry_after_.end() && retry->second > frame_counter_) continue;
      const node_t reference_node = ReferenceNode(*r.arc, id, near_node[static_cast<int>(r.role)]);
      if (reference_node == kInvalidNodeId) continue;
      const ArcImage reference_image = reference_node == r.arc->arc->to ? ArcImage::kB : ArcImage::kA;
      const TransferredPoint predicted = transfer.Transfer(point, *camera_, reference_image, margin);
      if (!predicted.in_image || !(predicted.distance_ratio > 0)) continue;
      const ReferencePatch* reference = Reference(reference_node, id);
      if (reference == nullptr) continue;
      // Segvic 2009 §5.2.1: initial scale = |Q - C_ref| / |Q - C_t| (the feature looks larger when nearer).
      const AlignmentResult refined =
          RefinePrediction(prediction_pyramid_, *reference, predicted.pixel, 1.0 / predicted.distance_ratio, refine_options_);
      if (refined.ok() && tracker_.AddFeature(*reference, refined, id) != kInvalidFeatureId) {
        reference_node_[id] = reference_node;
        retry_after_.erase(id);
        ++result->resumed;
        bearings_.erase(id);
      } else {
        retry_after_[id] = frame_counter_ + options_.retry_interval;
        ++result->rejected;
        result->marks.push_back({predicted.pixel, r.role, false});
      }
    }
  }

  // Without a transfer for the next arc (the current geometries share too few features with it and the map stores
  // no scale at b) or for the current arc (right after a transition), features seen in the nearby key-image are
  // predicted from the displacement of tracked neighbours seen there too: near that key-image the image motion is
  // locally coherent, and the acceptance test of RefinePrediction guards against wrong associations.
  if (next != nullptr && !predict_next && policy.next) ResumeFromNeighbours(*next, b, ArcRole::kNext, result);
  if (!predict_current) ResumeFromNeighbours(*arc, last_passed_ == b ? b : a, ArcRole::kCurrent, result);

  // Steering (Segvic 2009, eq. (10)): w = k * mean(x_t - x*) over the current arc's features, normalised
  // coordinates, x* in the next key-image I_i+1 = b.
  {
    const NodeData& node_b = Node(b);
    double sum = 0.0;
    int count = 0;
    for (const TrackedFeature& f : tracker_.Features()) {
      if (!arc->points.count(f.id)) continue;
      const auto target = node_b.bearings.find(f.id);
      Vector3d now;
      if (target == node_b.bearings.end() || target->second.z() <= 0) continue;
      if (!camera_->Unproject(f.warp.position, &now) || now.z() <= 0) continue;
      sum += now.x() / now.z() - target->second.x() / target->second.z();
      ++count;
    }
    if (count > 0) {
      result->steering = options_.steering_gain * sum / count;
      result->steering_valid = true;
    }
  }

  // Continuity: the camera moves steadily along the arc, so a position that jumps from the last accepted one (a
  // current geometry right after a transition or a bootstrap, estimated from few features, can place the camera
  // far ahead) is not believed: it decides no transition and makes the frame a bad one.
  const bool had_progress = progress_.has_value();
  const double last_progress = progress_ ? progress_->along : 0.0;
  if (position.valid) AcceptProgress(position.along);

  // Health: enough features of the current arc, a trustworthy current geometry and a continuous position, else
  // lost after a few frames.
  int current_tracked = 0;
  for (const TrackedFeature& f : tracker_.Features()) current_tracked += arc->points.count(f.id) ? 1 : 0;
  const bool good = current_tracked >= options_.min_features && (geometry_a.usable || geometry_b.usable) &&
                    fused.continuous;
  bad_frames_ = good ? 0 : bad_frames_ + 1;
  // No placement, and the camera's speed puts it well past the arc's end: it has most likely left the arc, and
  // nothing says for which one; the frame is reported lost rather than on a stale arc (the tracks are kept).
  stale_ = !position.valid && progress_ && progress_->speed_known &&
           ExpectedAlong(*progress_, frame_counter_) > 1.0 + options_.stale_margin;

  if (bad_frames_ >= options_.max_bad_frames) {
    spdlog::debug("repeat: lost at frame {} ({} features of arc {}, W_t:a {}, W_t:b {}, position {:.2f} after {:.2f})",
                  result->frame_index, current_tracked, arc_, geometry_a.usable, geometry_b.usable, position.along,
                  last_progress);
    state_ = LocalizerState::kLost;
    ClearTracks();
    progress_.reset();
    last_arc_ = arc_;
    lost_at_frame_ = frame_counter_;
    arc_ = kInvalidArcId;
    return;
  }

  // Topological transition (Segvic 2009 §5.2.2, eq. (9)) on the fused position: from the second frame on this arc,
  // or at once when the absolute pose placed the camera (a bootstrap that matched the key-image ahead of the camera
  // is corrected in its own frame; the current geometries' placements right after a bootstrap or transition are too
  // uncertain for that). It needs the absolute pose or both current geometries agreeing: one current geometry
  // alone, with the absolute pose rejected, placed the camera a third of an arc too far in the simulated town (a
  // transition two frames early).
  const bool decisive = fused.via_pose || (fused.via_from && fused.via_to);
  int direction =
      decisive && (had_progress || fused.via_pose) ? DecideTransition(position, options_.backward_margin) : 0;
  if ((direction > 0 && next == nullptr) || (direction < 0 && previous == nullptr)) direction = 0;
  if (direction == 0) return;
  // The camera has just crossed the plane through the node (eq. (9)). Its position and speed carry over into the new
  // arc's unit through the relative scale stored at the node: past b by the overshoot (before a by the undershoot
  // after a backward transition). Without a stored scale it is placed at the node with an unknown speed.
  const ArcProgress before = progress_.value_or(ArcProgress{direction > 0 ? 1.0 : 0.0, 0.0, frame_counter_, false});
  const arc_t left = arc_;
  ApplyTransition(direction, result);
  const auto carry = [this](const ArcProgress& old_progress, arc_t old_arc, int step) {
    const std::optional<double> factor = UnitRatio(old_arc, arc_, step);
    ArcProgress carried{step > 0 ? 0.0 : 1.0, 0.0, frame_counter_, false};
    if (factor) {
      carried.along = step > 0 ? std::max(0.0, old_progress.along - 1.0) * *factor
                               : 1.0 + std::min(0.0, old_progress.along) * *factor;
      carried.speed = old_progress.speed * *factor;
      carried.speed_known = old_progress.speed_known;
      carried.num_steps = old_progress.num_steps;
      for (int i = 0; i < old_progress.num_steps; ++i) carried.steps[i] = old_progress.steps[i] * *factor;
    }
    return carried;
  };
  progress_ = carry(before, left, direction);
  // Short arcs (dense key-images in turns, dropped frames): the camera may have passed the new arc's end too.
  if (direction > 0 && progress_->along > 1.0 && Arc(arc_)->next != kInvalidArcId) {
    const arc_t passed = arc_;
    const ArcProgress on_passed = *progress_;
    ApplyTransition(+1, result);
    result->transition = 2;
    progress_ = carry(on_passed, passed, +1);
  }
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

bool PositionContinuous(const std::optional<ArcProgress>& last, size_t frame, double along,
                        const ContinuityLimits& limits) {
  if (!last) return true;
  const double speed = last->speed_known ? last->speed : 0.0;
  const double expected = ExpectedAlong(*last, frame);
  // A camera that covers more than the limit per frame (short arcs) is allowed one frame of its motion as the
  // tolerance (not the motion of all frames since: one noisy speed would then excuse ever larger jumps).
  // The speed counts as known once it is the median of three steps (two right after a bootstrap, from placements
  // of few features, set it a third of an arc per frame too low in the simulated town).
  const bool speed_known = last->speed_known && last->num_steps >= static_cast<int>(last->steps.size());
  const double limit = speed_known ? limits.known_speed : limits.unknown_speed;
  return std::abs(along - expected) <= std::max(limit, std::abs(speed));
}

FusedArcPosition FuseArcPositions(const std::optional<ArcProgress>& last, size_t frame,
                                  const std::optional<PlacedCamera>& via_pose,
                                  const std::optional<PlacedCamera>& via_from,
                                  const std::optional<PlacedCamera>& via_to, const ContinuityLimits& limits,
                                  double agreement) {
  FusedArcPosition fused;
  const auto believed = [&](const std::optional<PlacedCamera>& placed) {
    return placed && placed->position.valid && PositionContinuous(last, frame, placed->position.along, limits);
  };
  if (believed(via_pose)) {
    fused.position = via_pose->position;
    fused.via_pose = true;
    return fused;
  }
  // The current geometries' placements that are believed; a placement that is not makes the frame discontinuous
  // when none is believed.
  bool rejected = via_pose && via_pose->position.valid;
  struct Candidate {
    const PlacedCamera* placed;
    bool from;
  };
  std::vector<Candidate> candidates;
  for (const auto& [placed, from] : {std::pair{&via_from, true}, std::pair{&via_to, false}}) {
    if (!placed->has_value() || !(*placed)->position.valid) continue;
    if (believed(*placed)) {
      candidates.push_back({&**placed, from});
    } else {
      rejected = true;
    }
  }
  if (candidates.empty()) {
    fused.continuous = !rejected;
    return fused;
  }
  // The most plausible first: nearest to where the motion puts the camera, or (no motion known) the lower σ_p.
  if (last) {
    const double expected = ExpectedAlong(*last, frame);
    std::sort(candidates.begin(), candidates.end(), [expected](const Candidate& x, const Candidate& y) {
      return std::abs(x.placed->position.along - expected) < std::abs(y.placed->position.along - expected);
    });
  } else {
    std::sort(candidates.begin(), candidates.end(),
              [](const Candidate& x, const Candidate& y) { return x.placed->sigma_p < y.placed->sigma_p; });
  }
  fused.position = candidates[0].placed->position;
  (candidates[0].from ? fused.via_from : fused.via_to) = true;
  if (candidates.size() == 2 &&
      std::abs(candidates[1].placed->position.along - fused.position.along) <= agreement) {
    const ArcPosition& other = candidates[1].placed->position;
    fused.position.along = 0.5 * (fused.position.along + other.along);
    fused.position.distance_to_from = 0.5 * (fused.position.distance_to_from + other.distance_to_from);
    fused.position.distance_to_to = 0.5 * (fused.position.distance_to_to + other.distance_to_to);
    fused.via_from = fused.via_to = true;
  }
  return fused;
}

void Localizer::AcceptProgress(double along) {
  ArcProgress accepted = progress_.value_or(ArcProgress());
  accepted.along = along;
  accepted.frame = frame_counter_;
  if (progress_ && frame_counter_ > progress_->frame) {
    // The speed along the arc (arc lengths per frame) is the median of the last three steps: one noisy position
    // (0.28 -> 0.95 -> 3.06 on an arc covered in 7 frames in the simulated town) must not set the expected motion.
    const double step = (along - progress_->along) / static_cast<double>(frame_counter_ - progress_->frame);
    for (int i = static_cast<int>(accepted.steps.size()) - 1; i > 0; --i) accepted.steps[i] = accepted.steps[i - 1];
    accepted.steps[0] = step;
    accepted.num_steps = std::min<int>(accepted.num_steps + 1, accepted.steps.size());
    accepted.speed = accepted.num_steps == 2 ? 0.5 * (accepted.steps[0] + accepted.steps[1])
                                             : Median(std::vector<double>(accepted.steps.begin(),
                                                                          accepted.steps.begin() + accepted.num_steps));
    accepted.speed_known = true;
  }
  progress_ = accepted;
}

void Localizer::ApplyTransition(int direction, FrameResult* result) {
  const ArcData* old_arc = Arc(arc_);
  arc_ = direction > 0 ? old_arc->next : old_arc->previous;
  result->transition = direction;
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
    for (const ArcData* candidate : {arc, next, previous}) kept |= candidate != nullptr && candidate->points.count(f.id);
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
  if (const ArcData* left = direction > 0 ? previous : next) RedefineReferences(*left, last_passed_, result);
}

void Localizer::RedefineReferences(const ArcData& arc, node_t node_id, FrameResult* result) {
  const NodeData& node = Node(node_id);
  // Camera centres of the arc's key-images in its frame (from = origin).
  const Vector3d centre_from = Vector3d::Zero();
  const Vector3d centre_to = CameraCentre(arc.arc->to_from_from);
  for (const TrackedFeature& f : std::vector<TrackedFeature>(tracker_.Features())) {
    const auto point = arc.points.find(f.id);
    const auto old_node = reference_node_.find(f.id);
    if (point == arc.points.end() || old_node == reference_node_.end() || old_node->second == node_id ||
        !node.positions.count(f.id)) {
      continue;
    }
    const ReferencePatch* reference = Reference(node_id, f.id);
    if (reference == nullptr) continue;
    // The apparent size relative to the new reference: the current scale times the ratio of the point's distances
    // to the old and the new reference viewpoints (1 when the old one is not on this arc).
    double ratio = 1.0;
    const auto centre = [&](node_t n) { return n == arc.arc->from ? centre_from : centre_to; };
    if (old_node->second == arc.arc->from || old_node->second == arc.arc->to) {
      const double to_old = (point->second - centre(old_node->second)).norm();
      const double to_new = (point->second - centre(node_id)).norm();
      if (to_old > 0 && to_new > 0) ratio = to_new / to_old;
    }
    const AlignmentResult aligned =
        RefinePrediction(prediction_pyramid_, *reference, f.warp.position, f.warp.scale * ratio, refine_options_);
    if (!aligned.ok()) continue;  // keeps tracking against its old reference
    tracker_.Remove(f.id);
    if (tracker_.AddFeature(*reference, aligned, f.id) != kInvalidFeatureId) {
      reference_node_[f.id] = node_id;
      ++result->redefined;
    } else {
      reference_node_.erase(f.id);
      ++result->dropped;
    }
  }
}

void Localizer::ResumeFromNeighbours(const ArcData& arc, node_t node_id, ArcRole role, FrameResult* result) {
  const NodeData& node = Node(node_id);
  // Rotation current_from_node from the tracked features seen in the key-image (Kabsch on bearings, twice with the
  // worst correspondences removed): near the key-image the translation hardly moves the features, while in turns the
  // rotation moves them by hundreds of pixels (so a local or translational model fails there).
  std::vector<Vector3d> key, now;
  std::vector<double> scales;
  for (const TrackedFeature& f : tracker_.Features()) {
    const auto it = node.bearings.find(f.id);
    const auto current = bearings_.find(f.id);
    if (it == node.bearings.end() || current == bearings_.end()) continue;
    key.push_back(it->second);
    now.push_back(current->second);
    const auto reference = reference_node_.find(f.id);
    scales.push_back(reference != reference_node_.end() && reference->second == node_id ? f.warp.scale : 1.0);
  }
  if (key.size() < 5) return;
  std::vector<bool> use(key.size(), true);
  Matrix3d rotation = Matrix3d::Identity();
  for (int round = 0; round < 3; ++round) {
    Matrix3d h = Matrix3d::Zero();
    for (size_t i = 0; i < key.size(); ++i) {
      if (use[i]) h += now[i] * key[i].transpose();
    }
    const Eigen::JacobiSVD<Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Matrix3d d = Matrix3d::Identity();
    d(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1.0 : 1.0;
    rotation = svd.matrixU() * d * svd.matrixV().transpose();
    std::vector<double> errors(key.size());
    for (size_t i = 0; i < key.size(); ++i) errors[i] = (rotation * key[i] - now[i]).norm();
    const double limit = std::max(3.0 * Median(errors), 2.0 / camera_->FocalLength());
    for (size_t i = 0; i < key.size(); ++i) use[i] = errors[i] <= limit;
  }
  ResumeByRotation(arc, node_id, rotation, Median(scales), role, result);
}

void Localizer::ResumeByRotation(const ArcData& arc, node_t node_id, const Matrix3d& rotation, double scale,
                                 ArcRole role, FrameResult* result) {
  const NodeData& node = Node(node_id);
  const double margin = tracker_.Options().alignment.window_size / 2 + 2;
  // The rotation-only prediction is biased by the translation (tens of pixels in kitti07's turns), the same way for
  // neighbouring features. Each candidate is aligned freely; the median offset of the converged ones corrects the
  // bias, and a feature is accepted only when its alignment agrees with the corrected prediction within the usual
  // radius — several independent features agreeing on one offset guard against wrong associations.
  struct Candidate {
    feature_t id;
    const ReferencePatch* reference;
    Vector2d predicted;
    AlignmentResult aligned;
  };
  std::vector<Candidate> candidates;
  std::vector<double> offset_x, offset_y;
  for (const auto& [id, point] : arc.points) {
    if (tracker_.Find(id) != nullptr) continue;
    const auto retry = retry_after_.find(id);
    if (retry != retry_after_.end() && retry->second > frame_counter_) continue;
    const auto bearing = node.bearings.find(id);
    if (bearing == node.bearings.end()) continue;
    Vector2d predicted;
    if (!camera_->Project(rotation * bearing->second, &predicted) || !camera_->InImage(predicted, margin)) continue;
    const ReferencePatch* reference = Reference(node_id, id);
    if (reference == nullptr) continue;
    WarpState initial;
    initial.position = predicted;
    initial.scale = scale;
    Candidate candidate{id, reference, predicted, AlignToReference(pyramid_, *reference, initial, refine_options_.alignment)};
    if (candidate.aligned.ok()) {
      offset_x.push_back(candidate.aligned.warp.position.x() - predicted.x());
      offset_y.push_back(candidate.aligned.warp.position.y() - predicted.y());
    }
    candidates.push_back(std::move(candidate));
  }
  const bool corrected = offset_x.size() >= 5;
  const Vector2d offset = corrected ? Vector2d(Median(offset_x), Median(offset_y)) : Vector2d::Zero();
  for (const Candidate& c : candidates) {
    const Vector2d predicted = c.predicted + offset;
    const double scale_ratio = c.aligned.warp.scale / scale;
    const bool accepted = corrected && c.aligned.ok() &&
                          (c.aligned.warp.position - predicted).norm() <= refine_options_.max_distance &&
                          scale_ratio <= refine_options_.max_scale_ratio &&
                          scale_ratio >= 1.0 / refine_options_.max_scale_ratio;
    if (accepted && tracker_.AddFeature(*c.reference, c.aligned, c.id) != kInvalidFeatureId) {
      reference_node_[c.id] = node_id;
      retry_after_.erase(c.id);
      ++result->resumed;
    } else {
      retry_after_[c.id] = frame_counter_ + options_.retry_interval;
      ++result->rejected;
      result->marks.push_back({predicted, role, false});
    }
  }
}

std::vector<Localizer::MatchedKeyImage> Localizer::MatchKeyImages(const WideBaselineFeatures& current,
                                                                 const std::vector<node_t>& candidates) {
  std::vector<MatchedKeyImage> verified;
  for (const node_t node : candidates) {
    const WideBaselineFeatures& key = NodeWideBaseline(node);
    const std::vector<cv::DMatch> matches = MatchWideBaseline(key, current, options_.matching);
    if (static_cast<int>(matches.size()) < options_.min_bootstrap_inliers) continue;
    MatchedKeyImage candidate;
    candidate.node = node;
    std::vector<Vector3d> bearings_key, bearings_current;
    std::vector<const cv::DMatch*> used;
    for (const cv::DMatch& m : matches) {
      const cv::KeyPoint& kk = key.keypoints[m.queryIdx];
      const cv::KeyPoint& kc = current.keypoints[m.trainIdx];
      Vector3d bk, bc;
      if (!camera_->Unproject(Vector2d(kk.pt.x, kk.pt.y), &bk) || !camera_->Unproject(Vector2d(kc.pt.x, kc.pt.y), &bc)) {
        continue;
      }
      bearings_key.push_back(bk);
      bearings_current.push_back(bc);
      used.push_back(&m);
    }
    candidate.geometry = EstimateRelativePose(bearings_key, bearings_current, camera_->FocalLength(), geometry_options_);
    // A frame taken (almost) where the key-image was shows no parallax: the rotation-only fit still verifies it.
    const bool verified_geometry = candidate.geometry.success ||
                                   candidate.geometry.failure == TwoViewFailure::kInsufficientParallax;
    if (!verified_geometry || candidate.geometry.num_inliers < options_.min_bootstrap_inliers) continue;
    for (size_t i = 0; i < used.size(); ++i) {
      if (!candidate.geometry.inlier_mask[i]) continue;
      const cv::KeyPoint& kk = key.keypoints[used[i]->queryIdx];
      const cv::KeyPoint& kc = current.keypoints[used[i]->trainIdx];
      candidate.key_points.emplace_back(kk.pt.x, kk.pt.y);
      candidate.current_points.emplace_back(kc.pt.x, kc.pt.y);
      candidate.size_ratios.push_back(kk.size > 0 && kc.size > 0 ? kc.size / kk.size : 1.0);
    }
    verified.push_back(std::move(candidate));
  }
  return verified;
}

std::vector<Localizer::MatchedKeyImage> Localizer::RetrieveKeyImages(const cv::Mat& image,
                                                                    const WideBaselineFeatures& current,
                                                                    const std::vector<node_t>& candidates,
                                                                    std::vector<node_t>* tried) {
  std::vector<node_t> ranked = candidates;
  const size_t shortlist = static_cast<size_t>(options_.retrieval_shortlist);
  if (shortlist > 0 && candidates.size() > shortlist) {
    std::vector<GlobalDescriptor> database;
    database.reserve(candidates.size());
    for (const node_t id : candidates) {
      NodeData& node = Node(id);
      if (!node.appearance) node.appearance = ComputeGlobalDescriptor(node.node->image, options_.retrieval);
      database.push_back(*node.appearance);
    }
    const std::vector<size_t> order =
        RankByGlobalDescriptor(ComputeGlobalDescriptor(image, options_.retrieval), database, options_.retrieval);
    for (size_t i = 0; i < order.size(); ++i) ranked[i] = candidates[order[i]];
  }
  const size_t first = shortlist > 0 ? std::min(shortlist, ranked.size()) : ranked.size();
  std::vector<MatchedKeyImage> verified = MatchKeyImages(current, {ranked.begin(), ranked.begin() + first});
  int best_inliers = 0;
  for (const MatchedKeyImage& m : verified) best_inliers = std::max(best_inliers, m.geometry.num_inliers);
  size_t matched = first;
  if (best_inliers < options_.retrieval_confident_inliers && first < ranked.size()) {
    // Not convincing (or nothing verified): the remaining candidates may hold the right key-image.
    std::vector<MatchedKeyImage> rest = MatchKeyImages(current, {ranked.begin() + first, ranked.end()});
    verified.insert(verified.end(), std::make_move_iterator(rest.begin()), std::make_move_iterator(rest.end()));
    matched = ranked.size();
  }
  tried->insert(tried->end(), ranked.begin(), ranked.begin() + matched);
  return verified;
}

std::vector<node_t> Localizer::NodesNear(arc_t arc_id, int arcs) const {
  std::vector<node_t> nodes;
  const auto add = [&nodes](node_t node) {
    if (std::find(nodes.begin(), nodes.end(), node) == nodes.end()) nodes.push_back(node);
  };
  const ArcData* forward = Arc(arc_id);
  const ArcData* backward = forward;
  for (int k = 0; k <= arcs && (forward != nullptr || backward != nullptr); ++k) {
    for (const ArcData* arc : {forward, backward}) {
      if (arc == nullptr) continue;
      add(arc->arc->from);
      add(arc->arc->to);
    }
    forward = forward != nullptr ? Arc(forward->next) : nullptr;
    backward = backward != nullptr ? Arc(backward->previous) : nullptr;
  }
  return nodes;
}

bool Localizer::Bootstrap(const Frame& frame, FrameResult* result) {
  const bool use_start_arc = start_arc_ != kInvalidArcId;
  const arc_t last_arc = last_arc_;
  ClearTracks();
  arc_ = kInvalidArcId;

  const WideBaselineFeatures current = ExtractWideBaselineFeatures(frame.image, options_.matching);
  std::vector<MatchedKeyImage> verified;
  std::vector<node_t> tried;
  if (use_start_arc) {
    const MapArc* arc = Arc(start_arc_)->arc;
    tried = {arc->from, arc->to};
    verified = MatchKeyImages(current, tried);
  } else {
    // After a loss the robot is still near where it was lost: only the key-images within a window of arcs around
    // the last arc are matched, widened with every frame since the loss; the whole map (retrieval) at the start
    // and for a robot lost for long (carried elsewhere). Look-alike streets elsewhere in the map verify too: in the
    // simulated town a frame 19 arcs from the truth matched a key-image with 42 inliers a frame after a loss.
    const size_t frames_lost = frame_counter_ - lost_at_frame_;
    std::vector<node_t> candidates;
    if (last_arc != kInvalidArcId && frames_lost < static_cast<size_t>(options_.global_relocalization_frames)) {
      candidates = NodesNear(last_arc, options_.relocalization_neighbourhood +
                                           static_cast<int>(frames_lost) * options_.relocalization_widening);
    } else {
      for (const MapNode& node : map_.nodes()) candidates.push_back(node.id);
    }
    verified = RetrieveKeyImages(frame.image, current, candidates, &tried);
  }
  result->key_images_matched = static_cast<int>(tried.size());
  if (verified.empty()) return false;
  const MatchedKeyImage* best = &*std::max_element(verified.begin(), verified.end(),
                                                   [](const MatchedKeyImage& x, const MatchedKeyImage& y) {
                                                     return x.geometry.num_inliers < y.geometry.num_inliers;
                                                   });
  const node_t best_node = best->node;
  const int best_inliers = best->geometry.num_inliers;

  // The arc: the given one, or the one on the side of the best key-image where the camera is (eq. (9)'s sign).
  arc_t chosen = start_arc_;
  if (!use_start_arc) {
    const node_t k = best->node;
    const MapArc* out = nullptr;
    const MapArc* in = nullptr;
    for (const auto& [id, data] : arcs_) {
      if (data->arc->from == k && (out == nullptr || data->arc->id < out->id)) out = data->arc;
      if (data->arc->to == k && (in == nullptr || data->arc->id < in->id)) in = data->arc;
    }
    if (out != nullptr && in != nullptr) {
      // The camera is beyond k on the outgoing arc when it lies in front of the plane through k perpendicular
      // to that arc's direction; W_t:k without parallax means "at k" (either arc is right).
      bool beyond = true;
      if (best->geometry.success) {
        const Vector3d c_t = CameraCentre(best->geometry.b_from_a);  // in k's frame
        const Vector3d c_next = CameraCentre(out->to_from_from);      // next key-image centre in k's frame
        beyond = c_t.dot(c_next) >= 0.0;
      }
      chosen = beyond ? out->id : in->id;
    } else {
      chosen = out != nullptr ? out->id : (in != nullptr ? in->id : kInvalidArcId);
    }
  }
  if (chosen == kInvalidArcId) return false;
  const ArcData* arc = Arc(chosen);
  best = nullptr;  // `verified` may grow below

  // The features are located through the key-images of the arc and of its neighbours: verify those the retrieval
  // did not try (with a start arc, its two key-images only).
  std::vector<node_t> untried;
  for (const ArcData* located : {arc, Arc(arc->previous), Arc(arc->next)}) {
    if (located == nullptr || use_start_arc) continue;
    for (const node_t node : {located->arc->from, located->arc->to}) {
      if (std::find(tried.begin(), tried.end(), node) == tried.end() &&
          std::find(untried.begin(), untried.end(), node) == untried.end()) {
        untried.push_back(node);
      }
    }
  }
  result->key_images_matched = static_cast<int>(tried.size() + untried.size());
  if (!untried.empty()) {
    std::vector<MatchedKeyImage> more = MatchKeyImages(current, untried);
    verified.insert(verified.end(), std::make_move_iterator(more.begin()), std::make_move_iterator(more.end()));
  }

  // Locate the mapped features of the arc and of its neighbours (all three are tracked from now on) in the frame:
  // each feature seen in a matched key-image is predicted from the displacement of the nearest matched key-points
  // there, then refined against the reference cut in that key-image.
  const double neighbour_radius = options_.bootstrap_neighbour_radius_px * pixel_scale_;
  RefinePredictionOptions refine = refine_options_;
  refine.max_distance = options_.bootstrap_radius_px * pixel_scale_;
  refine.max_scale_ratio = 1.5;
  for (const MatchedKeyImage& candidate : verified) {
    const NodeData& node = Node(candidate.node);
    for (const ArcData* located : {arc, Arc(arc->previous), Arc(arc->next)}) {
      if (located == nullptr || (candidate.node != located->arc->from && candidate.node != located->arc->to)) {
        continue;
      }
      for (const auto& [id, point] : located->points) {
        if (tracker_.Find(id) != nullptr) continue;
        const auto position = node.positions.find(id);
        if (position == node.positions.end()) continue;
        // The matched key-points within the radius (at least 2), else (distant structure, where SIFT finds little)
        // within twice the radius (at least 3) or three times (at least 4).
        std::vector<double> dx, dy, ratios;
        bool enough = false;
        for (int widening = 1; widening <= 3 && !enough; ++widening) {
          dx.clear();
          dy.clear();
          ratios.clear();
          for (size_t i = 0; i < candidate.key_points.size(); ++i) {
            if ((candidate.key_points[i] - position->second).norm() > widening * neighbour_radius) continue;
            const Vector2d d = candidate.current_points[i] - candidate.key_points[i];
            dx.push_back(d.x());
            dy.push_back(d.y());
            ratios.push_back(candidate.size_ratios[i]);
          }
          enough = static_cast<int>(dx.size()) >= widening + 1;
        }
        if (!enough) continue;
        const Vector2d predicted = position->second + Vector2d(Median(dx), Median(dy));
        if (!camera_->InImage(predicted, tracker_.Options().alignment.window_size / 2 + 2)) continue;
        const ReferencePatch* reference = Reference(candidate.node, id);
        if (reference == nullptr) continue;
        const AlignmentResult refined = RefinePrediction(prediction_pyramid_, *reference, predicted, Median(ratios), refine);
        if (refined.ok() && tracker_.AddFeature(*reference, refined, id) != kInvalidFeatureId) {
          reference_node_[id] = candidate.node;
          ++result->resumed;
        }
      }
    }
  }
  progress_.reset();
  if (tracker_.NumFeatures() < options_.min_bootstrap_features) {
    spdlog::debug("repeat: bootstrap at frame {} failed: {} features located around arc {} (key-image {}, {} inliers)",
                  frame.index, tracker_.NumFeatures(), chosen, best_node, best_inliers);
    ClearTracks();
    return false;
  }
  arc_ = chosen;
  start_arc_ = kInvalidArcId;  // the start arc serves the first bootstrap only
  spdlog::debug("repeat: frame {} localized on arc {} by matching key-image {} ({} inliers), {} features",
                frame.index, arc_, best_node, best_inliers, tracker_.NumFeatures());
  return true;
}

}  // namespace retrace
