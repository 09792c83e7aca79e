// Bootstrap and relocalization (Segvic 2009 §3.3; design §6): the current frame is related to key-images by
// wide-baseline matching (SIFT, ratio test, cross-check) and a verified relative pose, the arc chosen by which side
// of the best key-image the camera is on (the sign test of eq. (9)), and the mapped features of that arc and its
// neighbours located in the frame. Retrieval ranks candidate key-images by whole-image appearance first
// (the quantised thumbnails of AppearanceIndex) and verifies the most alike, in order, within a budget (issue 16).

#include <algorithm>
#include <array>
#include <cmath>
#include <unordered_map>
#include <unordered_set>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "retrace/geometry/essential.h"
#include "retrace/geometry/relative_pose.h"
#include "retrace/repeat/localizer_internal.h"
#include "retrace/util/point_grid.h"

namespace retrace {

using internal::Median;

namespace {

// min_bootstrap_features + λ ln(candidates / gate_candidates), rounded up, and no less than min_bootstrap_features.
int AContrarioFeatures(const LocalizerOptions& options, size_t candidates, int gate_candidates) {
  const double excess = static_cast<double>(candidates) / gate_candidates;
  if (excess <= 1.0) return options.min_bootstrap_features;
  return options.min_bootstrap_features +
         static_cast<int>(std::ceil(options.global_features_per_log_candidates * std::log(excess)));
}

}  // namespace

int GlobalBootstrapFeatures(const LocalizerOptions& options, size_t candidates) {
  return AContrarioFeatures(options, candidates, options.global_gate_candidates);
}

int SingleKeyImageBootstrapFeatures(const LocalizerOptions& options, size_t candidates) {
  if (options.single_key_image_gate_candidates <= 0) return -1;
  return AContrarioFeatures(options, candidates, options.single_key_image_gate_candidates);
}

std::vector<Localizer::MatchedKeyImage> Localizer::MatchKeyImages(const WideBaselineFeatures& current,
                                                                  const std::vector<node_t>& candidates,
                                                                  CandidateSource source) {
  const bool whole_map = source != CandidateSource::kNearby;
  const bool screening = source == CandidateSource::kWholeMapScreened;
  std::vector<MatchedKeyImage> verified;
  const int min_inliers =
      options_.binary_relocalization ? options_.min_binary_inliers : options_.min_bootstrap_inliers;
  // Bearings of every key-point (zero where the camera model has none), for guided matching.
  const auto unproject_all = [this](const WideBaselineFeatures& features) {
    std::vector<Vector3d> bearings(features.size(), Vector3d::Zero());
    for (size_t i = 0; i < features.size(); ++i) {
      const cv::Point2f& p = features.keypoints[i].pt;
      if (!camera_->Unproject(Vector2d(p.x, p.y), &bearings[i])) bearings[i].setZero();
    }
    return bearings;
  };
  std::vector<Vector3d> current_bearings;  // computed at the first guided matching
  for (const node_t node : candidates) {
    const WideBaselineFeatures& key = NodeWideBaseline(node);
    const std::vector<cv::DMatch> matches = MatchWideBaseline(key, current, relocalization_matching_);
    spdlog::debug("repeat: key-image {}: {} matches of {} and {} key-points", node, matches.size(), key.size(),
                  current.size());
    if (static_cast<int>(matches.size()) < min_inliers) continue;
    MatchedKeyImage candidate;
    candidate.node = node;
    std::vector<Vector3d> bearings_key, bearings_current;
    std::vector<const cv::DMatch*> used;
    for (const cv::DMatch& m : matches) {
      const cv::KeyPoint& kk = key.keypoints[m.queryIdx];
      const cv::KeyPoint& kc = current.keypoints[m.trainIdx];
      Vector3d bk, bc;
      if (!camera_->Unproject(Vector2d(kk.pt.x, kk.pt.y), &bk) ||
          !camera_->Unproject(Vector2d(kc.pt.x, kc.pt.y), &bc)) {
        continue;
      }
      bearings_key.push_back(bk);
      bearings_current.push_back(bc);
      used.push_back(&m);
    }
    // Screening a candidate of the whole map: it needs min_inliers inliers among these N matches, so a sample of 5 is all
    // inliers with probability at least (min_inliers / N)^5 when it can pass, and as many samples as find such a model
    // with the RANSAC's confidence are enough — fewer than the budget for the 30-60 matches a key-image of another
    // place gives (their full budget was most of a lost frame's time). Noisy minimal samples make that count
    // optimistic (LO-RANSAC's observation): the key-images verified to locate features take the full budget.
    TwoViewOptions geometry_options = relocalization_geometry_;
    if (screening && !bearings_key.empty()) {
      const int enough = internal::RequiredIterations(static_cast<double>(min_inliers) / bearings_key.size(), 5,
                                                      geometry_options.ransac.confidence);
      geometry_options.ransac.max_iterations = std::max(geometry_options.ransac.min_iterations,
                                                        std::min(geometry_options.ransac.max_iterations, enough));
    }
    candidate.geometry =
        EstimateRelativePose(bearings_key, bearings_current, camera_->FocalLength(), geometry_options);
    candidate.support = candidate.geometry.num_inliers;
    // A pose that enough matches support: matched again along its epipolar planes (guided_matching_min_inliers).
    std::vector<cv::DMatch> guided;
    if (candidate.geometry.success && !whole_map && options_.binary_relocalization &&
        options_.guided_matching_min_inliers > 0 &&
        candidate.geometry.num_inliers >= options_.guided_matching_min_inliers) {
      if (current_bearings.empty()) current_bearings = unproject_all(current);
      const Matrix3d essential = EssentialFromPose(candidate.geometry.b_from_a);  // current_from_key
      // The band: the RANSAC's inlier threshold, as an angle.
      const double band = relocalization_geometry_.ransac.max_error_px / camera_->FocalLength();
      const std::vector<Vector3d> key_bearings = unproject_all(key);
      guided = MatchAlongEpipolarPlanes(key, current, key_bearings, current_bearings, essential, band,
                                        relocalization_matching_);
      // Within a band most key-points are chance candidates, and a chance match lies on the band by construction:
      // only matches as close in descriptor as the pose's own inliers are kept (the largest Hamming distance among
      // them; on the validation drives chance matches along a band lie 20-30 bits farther at the median).
      float inlier_distance = 0.0f;
      for (size_t i = 0; i < used.size(); ++i) {
        if (candidate.geometry.inlier_mask[i]) inlier_distance = std::max(inlier_distance, used[i]->distance);
      }
      guided.erase(std::remove_if(guided.begin(), guided.end(),
                                  [inlier_distance](const cv::DMatch& m) { return m.distance > inlier_distance; }),
                   guided.end());
      std::vector<Vector3d> guided_key, guided_current;
      std::vector<const cv::DMatch*> guided_used;
      for (const cv::DMatch& m : guided) {  // (both bearings exist: MatchAlongEpipolarPlanes skips the others)
        guided_key.push_back(key_bearings[m.queryIdx]);
        guided_current.push_back(current_bearings[m.trainIdx]);
        guided_used.push_back(&m);
      }
      spdlog::debug("repeat: key-image {}: {} inliers, {} matches along the epipolar planes", node,
                    candidate.geometry.num_inliers, guided_key.size());
      if (static_cast<int>(guided_key.size()) >= min_inliers) {
        TwoViewGeometry again =
            EstimateRelativePose(guided_key, guided_current, camera_->FocalLength(), relocalization_geometry_);
        if (again.success && again.num_inliers > candidate.geometry.num_inliers) {
          candidate.geometry = std::move(again);
          used = std::move(guided_used);
        }
      }
    }
    // A frame taken (almost) where the key-image was shows no parallax: the rotation-only fit still verifies it.
    const bool verified_geometry = candidate.geometry.success ||
                                   candidate.geometry.failure == TwoViewFailure::kInsufficientParallax;
    if (!verified_geometry || candidate.geometry.num_inliers < min_inliers) continue;
    for (size_t i = 0; i < used.size(); ++i) {
      if (!candidate.geometry.inlier_mask[i]) continue;
      const cv::KeyPoint& kk = key.keypoints[used[i]->queryIdx];
      const cv::KeyPoint& kc = current.keypoints[used[i]->trainIdx];
      candidate.key_points.emplace_back(kk.pt.x, kk.pt.y);
      candidate.current_points.emplace_back(kc.pt.x, kc.pt.y);
      candidate.size_ratios.push_back(kk.size > 0 && kc.size > 0 ? kc.size / kk.size : 1.0);
      candidate.current_keypoints.push_back(used[i]->trainIdx);
    }
    verified.push_back(std::move(candidate));
  }
  return verified;
}

std::vector<Localizer::MatchedKeyImage> Localizer::RetrieveKeyImages(const cv::Mat& image,
                                                                     const WideBaselineFeatures& current,
                                                                     const std::vector<node_t>& candidates,
                                                                     std::vector<node_t>* tried, int shortlist,
                                                                     bool whole_map, int confident_reach) {
  // Rank by appearance: an exhaustive scan of the quantised thumbnails (about 0.3 µs per key-image).
  std::vector<size_t> entries;
  entries.reserve(candidates.size());
  for (const node_t id : candidates) entries.push_back(appearance_entry_.at(id));
  const cv::Mat query = QuantizeGlobalDescriptor(ComputeGlobalDescriptor(image, options_.retrieval));
  std::vector<size_t> order = appearance_index_.Rank(query, entries);
  // Over the whole map, fused with the ranking by visual words of the frame's binary descriptors (reciprocal rank
  // fusion). Not in the window of arcs around a loss: there the thumbnails find the place among a few tens of
  // key-images (recall@5 97 % in the validation drives), and over the validation matrix the fused order relocalized
  // 2-3 m beside the route on key-images whose tracks then lagged an arc (26 frames on a wrong arc instead of 19).
  const std::shared_ptr<const VisualWords>& words = map_.visual_words();
  if (whole_map && options_.visual_word_retrieval && words && !current.descriptors.empty() &&
      current.descriptors.type() == CV_8U && current.descriptors.cols == words->vocabulary.descriptor_bytes()) {
    order = FuseRankings(order, words->index.Rank(words->vocabulary.Words(current.descriptors), entries));
  }
  std::vector<node_t> ranked;
  ranked.reserve(candidates.size());
  for (const size_t entry : order) ranked.push_back(appearance_nodes_[entry]);
  // The verification budget: the most alike first, at most `shortlist` of them (0: every candidate, none skipped),
  // stopping at the first confident one — or, with `confident_reach`, at the first candidate ranked after it that is
  // not a key-image of the arcs within that many arcs of the first arc at it (NodesNear).
  const bool limited = shortlist > 0;
  const size_t budget = limited ? std::min(static_cast<size_t>(shortlist), ranked.size()) : ranked.size();
  std::vector<MatchedKeyImage> verified;
  std::optional<std::vector<node_t>> near_confident;  // the key-images within confident_reach of the first confident
  for (size_t i = 0; i < budget; ++i) {
    if (near_confident &&
        std::find(near_confident->begin(), near_confident->end(), ranked[i]) == near_confident->end()) {
      break;
    }
    tried->push_back(ranked[i]);
    std::vector<MatchedKeyImage> one =
        MatchKeyImages(current, {ranked[i]}, whole_map ? CandidateSource::kWholeMapScreened : CandidateSource::kNearby);
    spdlog::debug("repeat: retrieval candidate {} (rank {} of {}): {}", ranked[i], i, ranked.size(),
                  one.empty() ? std::string("not verified") : fmt::format("{} inliers", one.front().support));
    if (one.empty()) continue;
    const bool confident = one.front().support >= options_.retrieval_confident_inliers;
    verified.push_back(std::move(one.front()));
    if (!confident || !limited || near_confident) continue;
    if (confident_reach <= 0) break;
    const std::vector<const ArcData*> at = ArcsAt(ranked[i]);
    if (at.empty()) break;
    near_confident = NodesNear(at.front()->arc->id, confident_reach);
  }
  return verified;
}

std::vector<const Localizer::ArcData*> Localizer::ArcsAt(node_t node) const {
  std::vector<const ArcData*> at;
  for (const auto& [id, data] : arcs_) {
    if (HasEnd(*data->arc, node)) at.push_back(data.get());
  }
  std::sort(at.begin(), at.end(), [](const ArcData* a, const ArcData* b) { return a->arc->id < b->arc->id; });
  return at;
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
    // Along the route, and across a gap in the map on to the piece the teach drive made next (previous).
    if (forward != nullptr) forward = Arc(forward->next != kInvalidArcId ? forward->next : forward->next_piece);
    if (backward != nullptr) {
      backward = Arc(backward->previous != kInvalidArcId ? backward->previous : backward->previous_piece);
    }
  }
  return nodes;
}

int Localizer::AlternativeStarts() const {
  return last_arc_ == kInvalidArcId ? options_.start_alternative_starts : options_.bootstrap_alternative_starts;
}

AlignmentResult Localizer::AlignFromNearestMatches(const MatchedKeyImage& key_image, const PointGrid& matches,
                                                   const Vector2d& key_position, const Vector2d& median_start,
                                                   const ReferencePatch& reference,
                                                   const RefinePredictionOptions& refine, int margin) {
  // The matched key-points within the widest neighbourhood LocateMappedFeatures uses (three of its radii), nearest
  // first (then by index: the grid's order of visit does not matter).
  constexpr int kWidest = 3;
  const double radius = kWidest * options_.bootstrap_neighbour_radius_px * pixel_scale_;
  std::vector<std::pair<double, size_t>> nearest;
  matches.ForEachNear(key_position, kWidest, [&](size_t i) {
    const double distance = (key_image.key_points[i] - key_position).norm();
    if (distance <= radius) nearest.emplace_back(distance, i);
  });
  std::sort(nearest.begin(), nearest.end());
  // A start within half the accepted distance of one tried converges as that one did.
  const double separation = 0.5 * refine.max_distance;
  const size_t max_starts = 1 + static_cast<size_t>(AlternativeStarts());  // the median's and the alternatives
  Vector3d key_bearing;
  if (!camera_->Unproject(key_position, &key_bearing)) return {};
  std::vector<Vector2d> starts{median_start};
  for (const auto& [distance, i] : nearest) {
    if (starts.size() >= max_starts) break;
    const Vector2d start = key_position + key_image.current_points[i] - key_image.key_points[i];
    if (std::any_of(starts.begin(), starts.end(),
                    [&](const Vector2d& tried) { return (tried - start).norm() < separation; })) {
      continue;
    }
    starts.push_back(start);
    if (!camera_->InImage(start, margin)) continue;
    const AlignmentResult aligned =
        RefinePrediction(prediction_pyramid_, reference, start, key_image.size_ratios[i], refine);
    if (!aligned.ok()) continue;
    // Found from one match: it must be an inlier of the pose the key-image was verified with.
    Vector3d current_bearing;
    if (camera_->Unproject(aligned.warp.position, &current_bearing) &&
        IsInlierOfPose(key_image.geometry.b_from_a, key_bearing, current_bearing, camera_->FocalLength(),
                       relocalization_geometry_.ransac.max_error_px)) {
      return aligned;
    }
  }
  return {};
}

int Localizer::LocateMappedFeatures(const MatchedKeyImage& key_image, const std::array<const ArcData*, 3>& arcs,
                                    std::unordered_set<feature_t>* seen) {
  const double neighbour_radius = options_.bootstrap_neighbour_radius_px * pixel_scale_;
  RefinePredictionOptions refine = refine_options_;
  refine.max_distance = options_.bootstrap_radius_px * pixel_scale_;
  refine.max_scale_ratio = 1.5;
  refine.alignment.affine_fallback = options_.affine_fallback || options_.relocalization_affine_fallback;
  // The robust fallback (LocalizerOptions::relocalization_robust_alignment) is the last resort: a feature is located
  // by the paper's warp from the median displacement, else from the nearest matches, else robustly from the median.
  // Only after a loss: at a start nothing but this frame says where the camera is, and features matched in part
  // must not pull its first placement (a start 2.5 m beside the path was placed two arcs ahead with them).
  RefinePredictionOptions robust = refine;
  robust.alignment.robust_fallback = options_.relocalization_robust_alignment && last_arc_ != kInvalidArcId;
  const NodeData& node = Node(key_image.node);
  // (Cells a millionth wider than the radius: a match at the radius is inside the cells searched despite rounding.)
  const PointGrid matches(key_image.key_points, neighbour_radius * (1.0 + 1e-6));
  int located_features = 0;
  for (const ArcData* located : arcs) {
    if (located == nullptr || !HasEnd(*located->arc, key_image.node)) continue;
    for (const auto& [id, point] : located->points) {
      if (tracker_.Find(id) != nullptr) continue;
      const auto position = node.positions.find(id);
      if (position == node.positions.end()) continue;
      seen->insert(id);
      // The matched key-points within the radius (at least 2), else (distant structure, where SIFT finds little)
      // within twice the radius (at least 3) or three times (at least 4).
      std::vector<double> dx, dy, ratios;
      bool enough = false;
      for (int widening = 1; widening <= 3 && !enough; ++widening) {
        dx.clear();
        dy.clear();
        ratios.clear();
        matches.ForEachNear(position->second, widening, [&](size_t i) {
          if ((key_image.key_points[i] - position->second).norm() > widening * neighbour_radius) return;
          const Vector2d d = key_image.current_points[i] - key_image.key_points[i];
          dx.push_back(d.x());
          dy.push_back(d.y());
          ratios.push_back(key_image.size_ratios[i]);
        });
        enough = static_cast<int>(dx.size()) >= widening + 1;
      }
      if (!enough) continue;
      // (Medians of values: the order the grid visits the matches in does not change them.)
      const Vector2d predicted = position->second + Vector2d(Median(std::move(dx)), Median(std::move(dy)));
      const int margin = tracker_.Options().alignment.window_size / 2 + 2;
      if (!camera_->InImage(predicted, margin)) continue;
      const std::shared_ptr<const ReferencePatch> reference = Reference(key_image.node, id);
      if (reference == nullptr) continue;
      AlignmentResult refined =
          RefinePrediction(prediction_pyramid_, *reference, predicted, Median(std::move(ratios)), robust);
      if ((!refined.ok() || refined.robust_used) && AlternativeStarts() > 0) {
        // The paper's warp from the nearest matches before a robust alignment, which stays only when it fails.
        AlignmentResult paper =
            AlignFromNearestMatches(key_image, matches, position->second, predicted, *reference, refine, margin);
        if (paper.ok() || !refined.ok()) refined = paper;
      }
      if (refined.ok() && tracker_.AddFeature(reference, refined, id) != kInvalidFeatureId) {
        reference_node_[id] = key_image.node;
        ++located_features;
      }
    }
  }
  return located_features;
}

bool Localizer::OfArcOrNeighbours(const ArcData& arc, node_t node) const {
  for (const ArcData* around : {&arc, Arc(arc.previous), Arc(arc.next)}) {
    if (around != nullptr && HasEnd(*around->arc, node)) return true;
  }
  return false;
}

arc_t Localizer::ArcBySideOf(const MatchedKeyImage& key_image) const {
  const node_t k = key_image.node;
  const MapArc* out = nullptr;
  const MapArc* in = nullptr;
  for (const ArcData* data : ArcsAt(k)) {
    if (data->arc->from == k && out == nullptr) out = data->arc;
    if (data->arc->to == k && in == nullptr) in = data->arc;
  }
  if (out == nullptr || in == nullptr) return out != nullptr ? out->id : (in != nullptr ? in->id : kInvalidArcId);
  // The camera is beyond k on the outgoing arc when it lies in front of the plane through k that starts that arc (its
  // bisecting plane at k, placement.h; in k's frame, the outgoing arc's own); W_t:k without parallax means "at k"
  // (either arc is right). The camera centre in k's frame is the outgoing arc's frame.
  const bool beyond = !key_image.geometry.success || InFrontOfStartPlane(CameraCentre(key_image.geometry.b_from_a),
                                                                         out->to_from_from, Arc(out->id)->bounds);
  return beyond ? out->id : in->id;
}

bool Localizer::Bootstrap(const Frame& frame, FrameResult* result) {
  const bool use_start_arc = start_arc_ != kInvalidArcId;
  const arc_t last_arc = last_arc_;
  ClearTracks();
  verified_placement_.reset();
  arc_ = kInvalidArcId;
  // The place is decided on the features the paper's warp located: those the robust fallback added are tracked, but
  // a place is not taken on them (LocalizerOptions::relocalization_robust_alignment).
  const auto located_by_paper = [this]() { return tracker_.NumFeatures() - tracker_.NumRobustFeatures(); };

  const WideBaselineFeatures current = options_.binary_relocalization
                                          ? ExtractBinaryFeatures(frame.image, frame_features_)
                                          : ExtractWideBaselineFeatures(frame.image, options_.matching);
  std::vector<MatchedKeyImage> verified;
  std::vector<node_t> tried;
  size_t candidate_count = 2;
  bool global = false;  // retrieval over the whole map (a start without a start arc, or lost for long)
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
      global = true;
    }
    // Over the whole map most candidates are other places, and a lost robot's frame rate depends on how fast they
    // are refused (screening, MatchKeyImages); near where it was lost a candidate is likely the place: full budget.
    // Not localized since the start: the start's larger budget (LocalizerOptions::start_retrieval_shortlist), and
    // the candidates ranked after the first confident one that lie within the belief's reach of it verified too.
    const bool start = last_arc == kInvalidArcId;
    const int shortlist = start ? options_.start_retrieval_shortlist : options_.retrieval_shortlist;
    verified = RetrieveKeyImages(frame.image, current, candidates, &tried, shortlist, /*whole_map=*/global,
                                 /*confident_reach=*/start ? options_.belief.reach : 0);
    candidate_count = candidates.size();
  }
  result->key_images_matched = static_cast<int>(tried.size());
  if (verified.empty()) return false;
  const MatchedKeyImage* best = &*std::max_element(verified.begin(), verified.end(),
                                                   [](const MatchedKeyImage& x, const MatchedKeyImage& y) {
                                                     return x.geometry.num_inliers < y.geometry.num_inliers;
                                                   });
  const int min_features =
      global ? GlobalBootstrapFeatures(options_, candidate_count) : options_.min_bootstrap_features;
  // Two places that verified: the mapped features each locates through its own key-image decide between them, what
  // decides a place over the whole map (GlobalBootstrapFeatures): a look-alike may match the frame's key-points better
  // than the place itself (rows of equal blocks, another sun) but it does not show the place's mapped features. The
  // one locating more is taken (`best` set to it), unless the other locates almost as many
  // (retrieval_ambiguity_ratio) and at least `min_rival_features`: false, which is which not decided by this frame.
  std::unordered_map<node_t, int> located_alone_by_node;  // the best key-image may be weighed against two rivals
  const auto located_alone = [&](const MatchedKeyImage& key_image) {
    if (const auto known = located_alone_by_node.find(key_image.node); known != located_alone_by_node.end()) {
      return known->second;
    }
    const std::vector<const ArcData*> at = ArcsAt(key_image.node);
    std::array<const ArcData*, 3> arcs{};
    std::copy_n(at.begin(), std::min(at.size(), arcs.size()), arcs.begin());
    std::unordered_set<feature_t> seen;
    LocateMappedFeatures(key_image, arcs, &seen);
    const int located = located_by_paper();
    ClearTracks();
    located_alone_by_node.emplace(key_image.node, located);
    return located;
  };
  const auto decide_by_located_features = [&](const MatchedKeyImage* rival, int min_rival_features) {
    const int best_located = located_alone(*best), rival_located = located_alone(*rival);
    if (rival_located >= min_rival_features &&
        std::min(best_located, rival_located) >=
            options_.retrieval_ambiguity_ratio * std::max(best_located, rival_located)) {
      spdlog::debug("repeat: bootstrap at frame {} ambiguous: key-image {} locates {} features, key-image {} {}",
                    frame.index, best->node, best_located, rival->node, rival_located);
      return false;
    }
    if (rival_located > best_located) {
      spdlog::debug("repeat: bootstrap at frame {}: key-image {} ({} inliers) locates {} features, key-image {} ({}) "
                    "{}: the latter taken",
                    frame.index, best->node, best->geometry.num_inliers, best_located, rival->node,
                    rival->geometry.num_inliers, rival_located);
      best = rival;
    }
    return true;
  };
  if (!use_start_arc && options_.retrieval_ambiguity_ratio > 0.0 && verified.size() > 1) {
    // A look-alike place elsewhere verified almost as well: which one is right is not decided by this frame.
    const std::vector<const ArcData*> at_best = ArcsAt(best->node);
    const std::vector<node_t> near = NodesNear(at_best.empty() ? kInvalidArcId : at_best.front()->arc->id, 2);
    const MatchedKeyImage* rival = nullptr;  // the place elsewhere that verified best
    for (const MatchedKeyImage& other : verified) {
      if (std::find(near.begin(), near.end(), other.node) != near.end()) continue;
      if (other.geometry.num_inliers >= options_.retrieval_ambiguity_ratio * best->geometry.num_inliers) {
        spdlog::debug("repeat: bootstrap at frame {} ambiguous: key-image {} ({} inliers) and key-image {} ({})",
                      frame.index, best->node, best->geometry.num_inliers, other.node, other.geometry.num_inliers);
        return false;
      }
      if (rival == nullptr || other.geometry.num_inliers > rival->geometry.num_inliers) rival = &other;
    }
    // Over the whole map, the place elsewhere that verified best is weighed by the features each locates.
    if (rival != nullptr && global && !decide_by_located_features(rival, 0)) return false;
  }

  // The arc: the given one, or the one on the side of the best key-image where the camera is (eq. (9)'s sign).
  arc_t chosen = use_start_arc ? start_arc_ : ArcBySideOf(*best);
  if (!use_start_arc && global && options_.retrieval_ambiguity_ratio > 0.0 && chosen != kInvalidArcId) {
    // A key-image near the best one (within two arcs, no rival above) verified almost as well and puts the camera on
    // an arc that does not meet the chosen one: along a repeated facade, where the frame's key-points match a
    // key-image farther along shifted by a window or two, the relative pose does not refute it (the shift runs along
    // the epipolar lines), and neither does an absolute pose on mapped features located through those matches (a
    // start on seed2's map put 10 m ahead: `retrace bench kidnap --seed 2`). Weighed like a place elsewhere.
    // Not a key-image of the chosen arc or of its two neighbours, whose mapped features the bootstrap locates: near a
    // node two adjacent key-images may each put the camera beyond the other (side tests with little parallax), one
    // place all the same (the default drive's frame 125, `RepeatSim.KidnappedStartsRankedByAppearanceAndVisualWords`).
    const MatchedKeyImage* rival = nullptr;
    for (const MatchedKeyImage& other : verified) {
      if (OfArcOrNeighbours(*Arc(chosen), other.node) ||
          other.geometry.num_inliers < options_.retrieval_ambiguity_ratio * best->geometry.num_inliers) {
        continue;
      }
      const arc_t other_arc = ArcBySideOf(other);
      if (other_arc == kInvalidArcId || MeetAtANode(chosen, other_arc)) continue;
      if (rival == nullptr || other.geometry.num_inliers > rival->geometry.num_inliers) rival = &other;
    }
    if (rival != nullptr) {
      // A rival that locates too few mapped features to be localized at does not make the frame ambiguous: 2.5 m
      // beside the path a start verified key-images 1 and 3 with 42 and 35 inliers, which located 7 and 6 features
      // (validation drive beside106).
      const MatchedKeyImage* before = best;
      if (!decide_by_located_features(rival, min_features)) return false;
      if (best != before) chosen = ArcBySideOf(*best);
    }
  }
  const node_t best_node = best->node;
  const int best_inliers = best->geometry.num_inliers;
  if (chosen == kInvalidArcId) return false;
  const ArcData* arc = Arc(chosen);
  best = nullptr;  // `verified` may grow below

  // The features are located through the verified key-images of the arc and of its neighbours (with a start arc,
  // its two key-images only). Those retrieval did not try are verified lazily (the verifications are most of a
  // first frame's time): the arc's own first, its neighbours' outer key-images only when the features located so far
  // are too few or, over the whole map, the place not yet verified beyond one pair of images.
  const std::array<const ArcData*, 3> located_arcs = {arc, Arc(arc->previous), Arc(arc->next)};
  std::vector<node_t> untried_arc, untried_neighbours;
  for (const ArcData* located : located_arcs) {
    if (located == nullptr || use_start_arc) continue;
    for (const node_t node : {located->arc->from, located->arc->to}) {
      std::vector<node_t>& untried = HasEnd(*arc->arc, node) ? untried_arc : untried_neighbours;
      if (std::find(tried.begin(), tried.end(), node) == tried.end() &&
          std::find(untried.begin(), untried.end(), node) == untried.end()) {
        untried.push_back(node);
      }
    }
  }
  const auto verify = [&](const std::vector<node_t>& nodes) {
    if (nodes.empty()) return;
    result->key_images_matched += static_cast<int>(nodes.size());
    std::vector<MatchedKeyImage> more =
        MatchKeyImages(current, nodes, global ? CandidateSource::kWholeMap : CandidateSource::kNearby);
    verified.insert(verified.end(), std::make_move_iterator(more.begin()), std::make_move_iterator(more.end()));
  };
  // Over the whole map, the place must be verified beyond one pair of images: enough key-images of the arc and of
  // its neighbours verify (LocalizerOptions::min_global_agreeing_key_images; a look-alike place mostly verifies one).
  const auto agreeing = [&]() {
    return static_cast<int>(std::count_if(verified.begin(), verified.end(), [&](const MatchedKeyImage& candidate) {
      return OfArcOrNeighbours(*arc, candidate.node);
    }));
  };

  // Located through each verified key-image once, in the order verified.
  std::unordered_set<feature_t> seen;  // mapped features of the three arcs seen in a verified key-image
  size_t located_through = 0;
  const auto locate = [&]() {
    for (; located_through < verified.size(); ++located_through) {
      result->resumed += LocateMappedFeatures(verified[located_through], located_arcs, &seen);
    }
  };

  const int min_agreeing = global ? options_.min_global_agreeing_key_images : 1;
  verify(untried_arc);
  if (agreeing() >= min_agreeing) locate();
  int needed_features = min_features;
  if (agreeing() < min_agreeing || located_by_paper() < min_features) {
    verify(untried_neighbours);
    if (agreeing() < min_agreeing) {
      // Verified by one key-image only: test (3) of LocalizerOptions, more located features instead.
      const int single_features = SingleKeyImageBootstrapFeatures(options_, candidate_count);
      if (single_features < 0) {
        spdlog::debug(
            "repeat: bootstrap at frame {} failed: {} of the key-images around arc {} verified (key-image "
            "{}, {} inliers)",
            frame.index, agreeing(), chosen, best_node, best_inliers);
        ClearTracks();
        return false;
      }
      needed_features = std::max(min_features, single_features);
    }
    locate();
  }
  if (located_by_paper() < needed_features) {
    // Not localized by the arc's reconstruction, but the verified key-images may place the camera — near where it was
    // lost or started, not over the whole map, where look-alike places verify too and only the mapped features they
    // locate tell them apart (GlobalBootstrapFeatures).
    if (options_.place_by_verified_key_images && !global) {
      verified_placement_ = PlaceByVerifiedKeyImages(*arc, verified);
      if (verified_placement_) {
        spdlog::debug("repeat: frame {} placed on arc {} at {:.3f} (sigma {:.3f}) by its verified key-images",
                      frame.index, chosen, verified_placement_->along, verified_placement_->sigma);
      }
    }
    spdlog::debug(
        "repeat: bootstrap at frame {} failed: {} of {} features located around arc {} ({} needed; {} more by the "
        "robust fallback; key-image {}, {} inliers, {} key-images of the place verified)",
        frame.index, located_by_paper(), seen.size(), chosen, needed_features, tracker_.NumRobustFeatures(), best_node,
        best_inliers, agreeing());
    ClearTracks();
    return false;
  }
  arc_ = chosen;
  start_arc_ = kInvalidArcId;  // the start arc serves the first bootstrap only
  // The key-image is a measurement of the belief (placement.h), picked among the candidates.
  bootstrap_key_image_ = BootstrapKeyImage{chosen, best_node, static_cast<int>(candidate_count)};
  spdlog::debug("repeat: frame {} localized on arc {} by matching key-image {} ({} inliers), {} of {} features",
                frame.index, arc_, best_node, best_inliers, tracker_.NumFeatures(), seen.size());
  return true;
}

std::vector<std::pair<node_t, Rigid3d>> Localizer::KeyImagesInArcFrame(const ArcData& arc) const {
  // The arc's own two, and the outer key-images of its neighbours through their geometries, carried into the arc's
  // unit by the relative scale stored at the node they share (UnitRatio; a neighbour without one is left out).
  const Rigid3d& b_from_a = arc.arc->to_from_from;
  const auto in_arc_unit = [&](const ArcData& other, int direction) -> std::optional<Rigid3d> {
    const std::optional<double> ratio = UnitRatio(arc.arc->id, other.arc->id, direction);  // arc's unit -> other's
    if (!ratio) return std::nullopt;
    Rigid3d geometry = other.arc->to_from_from;
    geometry.translation /= *ratio;
    return geometry;
  };
  std::vector<std::pair<node_t, Rigid3d>> key_from_arc = {{arc.arc->from, Rigid3d()}, {arc.arc->to, b_from_a}};
  if (const ArcData* previous = Arc(arc.previous); previous != nullptr) {
    if (const std::optional<Rigid3d> a_from_z = in_arc_unit(*previous, -1)) {
      key_from_arc.emplace_back(previous->arc->from, a_from_z->Inverse());
    }
  }
  if (const ArcData* next = Arc(arc.next); next != nullptr) {
    if (const std::optional<Rigid3d> c_from_b = in_arc_unit(*next, +1)) {
      key_from_arc.emplace_back(next->arc->to, *c_from_b * b_from_a);
    }
  }
  return key_from_arc;
}

std::optional<PlaceMeasurement> Localizer::PlaceByVerifiedKeyImages(
    const ArcData& arc, const std::vector<MatchedKeyImage>& verified) const {
  const Rigid3d& b_from_a = arc.arc->to_from_from;
  std::vector<KeyImageMatches> views;
  for (const auto& [node, pose] : KeyImagesInArcFrame(arc)) {
    const MatchedKeyImage* best = nullptr;  // the key-image's verification with the most inliers
    for (const MatchedKeyImage& candidate : verified) {
      if (candidate.node == node && candidate.geometry.success &&
          (best == nullptr || candidate.geometry.num_inliers > best->geometry.num_inliers)) {
        best = &candidate;
      }
    }
    if (best == nullptr) continue;
    KeyImageMatches view;
    view.key_from_arc = pose;
    for (size_t i = 0; i < best->key_points.size(); ++i) {
      Vector3d key_bearing, current_bearing;
      if (!camera_->Unproject(best->key_points[i], &key_bearing) ||
          !camera_->Unproject(best->current_points[i], &current_bearing)) {
        continue;
      }
      view.current_keypoints.push_back(best->current_keypoints[i]);
      view.key_bearings.push_back(key_bearing);
      view.current_bearings.push_back(current_bearing);
    }
    views.push_back(std::move(view));
  }
  if (views.size() < 2) return std::nullopt;
  // A point within twice the verification's inlier threshold of each key-image's ray (both ends of a match err).
  const double max_angle = 2.0 * relocalization_geometry_.ransac.max_error_px / camera_->FocalLength();
  const AbsolutePose pose = ResectFromKeyImages(views, max_angle, camera_->FocalLength(), pose_options_);
  if (!pose.success) return std::nullopt;
  const ArcPosition position = LocateOnArc(pose.cam_from_world, b_from_a, arc.bounds);
  if (!position.valid) return std::nullopt;
  return VerifiedPoseMeasurement(arc.arc->id, position, pose, b_from_a, options_.placement, arc.bounds);
}

}  // namespace retrace
