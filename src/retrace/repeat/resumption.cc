// Resumption of mapped features (Segvic 2009 §5.2.1) and redefinition of references at transitions (§5.2.2).
//
// A mapped feature that is not tracked is predicted in the current image — by the decomposed point transfer of its
// arc (ResumePredicted), or, where no transfer is available, by the rotation between a nearby key-image and the
// current image (ResumeFromNeighbours) — and refined against its reference appearance cut from a key-image; it is
// accepted only when the refinement converges near the prediction with a plausible scale. Prudence (eqs. (7), (8))
// decides which neighbouring arcs may be resumed at all.

#include <algorithm>

#include <Eigen/SVD>

#include "retrace/repeat/localizer_internal.h"

namespace retrace {

using internal::Median;


void Localizer::ResumePredicted(const std::array<RolePredictor, 3>& roles, const ArcPosition& position,
                                FrameResult* result) {
  const ResumptionPolicy policy = DecideResumption(position, options_.next_arc_ratio, options_.previous_arc_ratio);
  const double margin = tracker_.Options().alignment.window_size / 2 + 2;
  const ArcData* arc = roles[0].arc;
  const node_t a = arc->arc->from;
  const node_t b = arc->arc->to;
  // References are cut from the arc's key-image nearest to the camera (see LocalizerOptions / header).
  std::array<node_t, 3> near_node{};
  near_node[static_cast<int>(ArcRole::kCurrent)] = position.valid && position.along < 0.5 ? a : b;
  near_node[static_cast<int>(ArcRole::kNext)] = b;
  near_node[static_cast<int>(ArcRole::kPrevious)] = a;
  for (const RolePredictor& r : roles) {
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
      const std::shared_ptr<const ReferencePatch> reference = Reference(reference_node, id);
      if (reference == nullptr) continue;
      // Segvic 2009 §5.2.1: initial scale = |Q - C_ref| / |Q - C_t| (the feature looks larger when nearer).
      const AlignmentResult refined = RefinePrediction(prediction_pyramid_, *reference, predicted.pixel,
                                                       1.0 / predicted.distance_ratio, refine_options_);
      if (refined.ok() && tracker_.AddFeature(reference, refined, id) != kInvalidFeatureId) {
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
    const std::shared_ptr<const ReferencePatch> reference = Reference(node_id, f.id);
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
    if (tracker_.AddFeature(reference, aligned, f.id) != kInvalidFeatureId) {
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
    std::shared_ptr<const ReferencePatch> reference;
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
    const std::shared_ptr<const ReferencePatch> reference = Reference(node_id, id);
    if (reference == nullptr) continue;
    WarpState initial;
    initial.position = predicted;
    initial.scale = scale;
    Candidate candidate{id, reference, predicted,
                        AlignToReference(pyramid_, *reference, initial, refine_options_.alignment)};
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
    if (accepted && tracker_.AddFeature(c.reference, c.aligned, c.id) != kInvalidFeatureId) {
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

}  // namespace retrace
