#include "retrace/nav/navigator.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "retrace/feature/global_descriptor.h"
#include "retrace/geometry/planar_pose.h"
#include "retrace/teach/matched_geometry.h"

namespace retrace {

WideBaselineOptions NavigationMatchingDefaults() {
  WideBaselineOptions options;
  options.max_harris_keypoints = 0;
  options.max_mser_keypoints = 0;
  options.ratio = 0.8;
  return options;
}

bool NavigatorOptions::Check(std::string* error) const {
  const auto fail = [error](const std::string& message) {
    if (error != nullptr) *error = message;
    return false;
  };
  std::string part;
  if (!planning.Check(&part)) return fail("planning: " + part);
  if (!heading.Check(&part)) return fail("heading: " + part);
  if (!matching.Check(&part)) return fail("matching: " + part);
  if (!(min_similarity > 0 && min_similarity <= 1)) {
    return fail(fmt::format("min_similarity must be in (0, 1], got {}", min_similarity));
  }
  if (localization_candidates < 0) {
    return fail(fmt::format("localization_candidates must be >= 0 (0 = all), got {}", localization_candidates));
  }
  if (!(look_ahead > 0 && look_ahead <= 1000)) return fail(fmt::format("look_ahead must be in (0, 1000] m, got {}", look_ahead));
  if (!(speed > 0 && speed <= 50)) return fail(fmt::format("speed must be in (0, 50] m/s, got {}", speed));
  if (follow_taught_arcs && !localizer.Check(&part)) return fail("localizer: " + part);
  if (!(image_steering_gain >= 0 && image_steering_gain <= 100)) {
    return fail(fmt::format("image_steering_gain must be in [0, 100] 1/m, got {}", image_steering_gain));
  }
  if (max_cached_key_images < 1) {
    return fail(fmt::format("max_cached_key_images must be >= 1, got {}", max_cached_key_images));
  }
  return true;
}

const char* NavigationStateName(NavigationState state) {
  switch (state) {
    case NavigationState::kLocalizing:
      return "localizing";
    case NavigationState::kNavigating:
      return "navigating";
    case NavigationState::kAtGoal:
      return "at_goal";
    case NavigationState::kNoPath:
      return "no_path";
  }
  return "?";
}

Navigator::Navigator(Map map, const CameraModel& camera, node_t goal, const NavigatorOptions& options)
    : map_(std::move(map)), camera_(camera.Clone()), goal_(goal), options_(options), filter_(options.heading) {
  std::string error;
  if (!options_.Check(&error)) throw std::invalid_argument("NavigatorOptions: " + error);
  if (map_.FindNode(goal_) == nullptr) throw std::invalid_argument(fmt::format("the goal {} is not a node of the map", goal_));
  if (options_.level_camera) {
    camera_mount_ = EstimateCameraMount(map_, options_.camera_mount);
    spdlog::info("navigator: camera tilted {:.2f} deg against the ground (from {} arc translations and {} turns; {} "
                 "outliers dropped)", camera_mount_.tilt_rad() * 180 / M_PI, camera_mount_.translations,
                 camera_mount_.rotations, camera_mount_.dropped);
  }
  graph_ = BuildPlanningGraph(map_, options_.planning);
  paths_to_goal_ = ShortestPathsToGoal(graph_, goal_);
  // The localizer takes the map (a copy would duplicate its features and signatures); map() reads it from there.
  if (options_.follow_taught_arcs && !map_.arcs().empty()) {
    localizer_ = std::make_unique<Localizer>(std::move(map_), *camera_, options_.localizer);
  }
}

void Navigator::SetPlan(node_t start) {
  planned_path_ = PathFromTree(paths_to_goal_, start, goal_);
  if (localizer_) localizer_->SetPlannedArcs(planned_path_.found ? planned_path_.arcs : std::vector<arc_t>());
  // The plan's places: its key-images and those linked to them (two images of one place, where drives overlap),
  // each with its position along the plan.
  planned_places_.clear();
  if (!planned_path_.found) return;
  for (size_t i = 0; i < planned_path_.nodes.size(); ++i) planned_places_.emplace(planned_path_.nodes[i], i);
  for (size_t i = 0; i < planned_path_.nodes.size(); ++i) {
    const node_t node = planned_path_.nodes[i];
    for (const MapArc* arc : map().ArcsFrom(node)) {
      if (arc->IsLink()) planned_places_.emplace(arc->to, i);
    }
    for (const MapArc* arc : map().ArcsTo(node)) {
      if (arc->IsLink()) planned_places_.emplace(arc->from, i);
    }
  }
}

std::optional<double> Navigator::FollowLocalizer(const cv::Mat& image, NavigationStep* step) {
  Frame frame;
  frame.index = frame.source_index = frames_++;
  frame.image = image;
  const FrameResult result = localizer_->ProcessFrame(frame);
  step->localizer_state = result.state;
  step->localizer_confidence = result.confidence;
  if (result.state != LocalizerState::kTracking) return std::nullopt;
  step->arc = result.arc;
  const MapArc* arc = map().FindArc(result.arc);
  if (arc == nullptr || at_goal_ || subgoal_ == kInvalidNodeId || !planned_path_.found) return std::nullopt;
  // On the plan in the arc's taught direction: from a place of the plan to a later one (the plan's own arc, or one
  // of another drive over the same street).
  const auto from = planned_places_.find(arc->from);
  const auto to = planned_places_.find(arc->to);
  if (from != planned_places_.end() && to != planned_places_.end()) {
    step->on_plan = from->second < to->second;
    // Image steering along a driven arc (a link joins two views of one place: no line to keep).
    if (step->on_plan && !arc->IsLink() && result.steering_valid) return result.steering;
    return std::nullopt;
  }
  if (from != planned_places_.end() || to != planned_places_.end() || paths_to_goal_.distance.count(arc->to) == 0) {
    return std::nullopt;
  }
  // Another branch than the plan's: plan again from the key-image the robot drives towards.
  spdlog::info("navigator: the localizer tracks arc {} ({} -> {}, confidence {:.3f}) off the plan: planning again "
               "from key-image {}", arc->id, arc->from, arc->to, result.confidence, arc->to);
  SetPlan(arc->to);
  previous_ = arc->from;
  subgoal_ = arc->to;
  filter_.Reset();
  ++replans_;
  step->replanned = true;
  return std::nullopt;
}

Navigator::KeyImageFeatures Navigator::Describe(const cv::Mat& image) const {
  KeyImageFeatures result;
  result.features = ExtractWideBaselineFeatures(image, options_.matching);
  result.bearings.resize(result.features.size(), Vector3d::Zero());
  for (size_t i = 0; i < result.features.size(); ++i) {
    const cv::Point2f& p = result.features.keypoints[i].pt;
    Vector3d bearing;
    if (camera_->Unproject(Vector2d(p.x, p.y), &bearing)) {
      result.bearings[i] = camera_mount_.level_from_camera * bearing.normalized();
    }
  }
  return result;
}

const Navigator::KeyImageFeatures& Navigator::FeaturesOf(node_t node) {
  auto found = cache_.find(node);
  if (found != cache_.end()) {
    cache_order_.remove(node);
    cache_order_.push_front(node);
    return found->second;
  }
  while (cache_.size() >= static_cast<size_t>(options_.max_cached_key_images) && !cache_order_.empty()) {
    cache_.erase(cache_order_.back());
    cache_order_.pop_back();
  }
  cache_order_.push_front(node);
  return cache_.emplace(node, Describe(map().KeyImage(node))).first->second;
}

Navigator::Comparison Navigator::Compare(node_t node, int* compared) {
  if (const auto done = comparisons_.find(node); done != comparisons_.end()) return done->second;
  const KeyImageFeatures& key_image = FeaturesOf(node);
  ++*compared;
  Comparison comparison;
  std::vector<Vector3d> bearings_current, bearings_key_image;
  for (const cv::DMatch& match : MatchWideBaseline(current_.features, key_image.features, options_.matching)) {
    const Vector3d& a = current_.bearings[match.queryIdx];
    const Vector3d& b = key_image.bearings[match.trainIdx];
    if (a.isZero() || b.isZero()) continue;
    bearings_current.push_back(a);
    bearings_key_image.push_back(b);
  }
  if (bearings_current.size() >= 3) {
    comparison.geometry =
        EstimatePlanarRelativePose(bearings_current, bearings_key_image, camera_->FocalLength(), options_.geometry);
    // Booij 2007 §B.2 (AppearanceSimilarity). An estimate refused only for its parallax still counts its matches:
    // the robot stands at the key-image's place.
    if (comparison.geometry.success || comparison.geometry.failure == TwoViewFailure::kInsufficientParallax) {
      comparison.similarity = AppearanceSimilarity(comparison.geometry.num_inliers, current_.features.size(),
                                                   key_image.features.size());
    }
  }
  comparison.matches = comparison.similarity >= options_.min_similarity &&
                       comparison.geometry.num_inliers >= options_.geometry.min_inliers;
  spdlog::debug("navigator: key-image {}: {} matches, {} inliers ({}), similarity {:.3f}", node,
                bearings_current.size(), comparison.geometry.num_inliers,
                comparison.geometry.success ? "geometry" : TwoViewFailureName(comparison.geometry.failure),
                comparison.similarity);
  comparisons_.emplace(node, comparison);
  return comparison;
}

node_t Navigator::Localize(int* compared) {
  std::vector<node_t> candidates;
  for (const MapNode& node : map().nodes()) candidates.push_back(node.id);
  if (options_.localization_candidates > 0 && static_cast<size_t>(options_.localization_candidates) < candidates.size()) {
    // The key-images' quantised thumbnails (stored with the map's signatures; computed for maps without them or
    // made at another size), indexed once; the image's thumbnail ranks them.
    const cv::Mat query = QuantizeGlobalDescriptor(ComputeGlobalDescriptor(current_image_));
    if (!appearance_index_) {
      appearance_index_ = std::make_unique<AppearanceIndex>();
      for (const node_t id : candidates) {
        cv::Mat thumbnail = map().Signature(id).appearance;
        if (thumbnail.size() != query.size() || thumbnail.type() != query.type()) {
          thumbnail = QuantizeGlobalDescriptor(ComputeGlobalDescriptor(map().KeyImage(id)));
        }
        appearance_index_->Add(thumbnail);
      }
    }
    std::vector<size_t> all(candidates.size());
    std::iota(all.begin(), all.end(), 0);
    std::vector<node_t> ranked;
    for (const size_t i : appearance_index_->Rank(query, all)) {
      ranked.push_back(candidates[i]);
      if (ranked.size() == static_cast<size_t>(options_.localization_candidates)) break;
    }
    candidates = ranked;
  }
  node_t best = kInvalidNodeId;
  double best_similarity = 0.0;
  for (node_t id : candidates) {
    const Comparison comparison = Compare(id, compared);
    if (comparison.matches && comparison.similarity > best_similarity) {
      best = id;
      best_similarity = comparison.similarity;
    }
  }
  return best;
}

std::optional<double> HeadingAlongArc(const Map& map, node_t from, node_t to, const Matrix3d& from_from_robot,
                                      const Matrix3d& level_from_camera) {
  // `to`'s camera centre in `from`'s camera frame, from the taught arc either way (x_to = R x_from + t).
  std::optional<Vector3d> centre;
  for (const MapArc* arc : map.ArcsFrom(from)) {
    if (arc->to == to) centre = -arc->to_from_from.rotation.transpose() * arc->to_from_from.translation;
  }
  for (const MapArc* arc : map.ArcsTo(from)) {
    if (!centre && arc->from == to) centre = arc->to_from_from.translation;
  }
  if (!centre || centre->norm() < 1e-9) return std::nullopt;
  // Levelled as the bearings are, then into the robot's frame; the robot's offset from `from` is neglected.
  const Vector3d in_robot = from_from_robot.transpose() * (level_from_camera * *centre);
  return std::atan2(in_robot.x(), in_robot.z());
}

double Navigator::Curvature(double heading) const {
  // Pure pursuit towards the point at distance ℓ in the direction φ (positive right): κ = 2 sin φ / ℓ to the right,
  // the largest turn (2 / ℓ) for a point beside or behind. Curvature is positive left.
  const double turn = std::abs(heading) >= M_PI / 2 ? 1.0 : std::sin(std::abs(heading));
  return -std::copysign(2.0 * turn / options_.look_ahead, heading);
}

NavigationStep Navigator::ProcessImage(const cv::Mat& image) {
  const auto start = std::chrono::steady_clock::now();
  NavigationStep step;
  comparisons_.clear();
  current_image_ = image;
  current_ = Describe(image);
  // The localizer first: it may find the robot off the plan and replan before the subgoal is updated.
  const std::optional<double> image_steering = localizer_ ? FollowLocalizer(image, &step) : std::nullopt;

  if (at_goal_) {
    step.state = NavigationState::kAtGoal;
    step.subgoal = subgoal_;
  } else {
    // (Re)localization: at the start, and after max_misses images in a row without a heading (Booij 2007 §B.4).
    bool localized = subgoal_ != kInvalidNodeId && !filter_.NeedsRelocalization();
    if (!localized) {
      const bool recovering = subgoal_ != kInvalidNodeId;
      const node_t found = Localize(&step.compared);
      if (found != kInvalidNodeId) {
        SetPlan(found);
        spdlog::debug("navigator: localized at key-image {} (similarity {:.3f}), {} to the goal", found,
                      comparisons_.at(found).similarity,
                      planned_path_.found ? fmt::format("{} key-images", planned_path_.nodes.size())
                                          : std::string("no path"));
        step.relocalized = true;
        relocalizations_ += recovering;
        filter_.Reset();
        previous_ = kInvalidNodeId;
        subgoal_ = planned_path_.found ? found : kInvalidNodeId;
        localized = planned_path_.found;
        step.state = localized ? NavigationState::kNavigating : NavigationState::kNoPath;
      } else if (recovering) {
        filter_.Update(std::nullopt);  // still lost: the misses go on counting
      }
    }
    if (!localized) {
      // Not localized (or nowhere to go from here): stand still and try again with the next image.
      if (step.state != NavigationState::kNoPath) step.state = NavigationState::kLocalizing;
      step.subgoal = subgoal_;
    } else {
      // Dynamic subgoal (Booij 2007 §B.4, subgoal.h).
      const SubgoalUpdate update = AdvanceSubgoal(graph_, paths_to_goal_.distance, subgoal_, goal_, [&](node_t node) {
        return Compare(node, &step.compared).matches;
      });
      subgoal_ = update.subgoal;
      step.advanced = update.advanced;
      step.subgoal = subgoal_;
      step.state = NavigationState::kNavigating;

      if (update.advanced > 0) previous_ = update.previous;

      // Heading towards the subgoal: eq. (B.4) on the planar geometry of this image and the subgoal's key-image.
      const Comparison comparison = Compare(subgoal_, &step.compared);
      step.similarity = comparison.similarity;
      const bool is_goal = subgoal_ == goal_;
      // The paper's heading needs only a geometry (it is missing when fewer than 3-4 points correspond), not a
      // match strong enough to advance the subgoal.
      bool reached = false;  // the robot is at the subgoal or past it
      std::optional<double> heading;  // the measurement the robot steers by
      bool heading_matches = comparison.matches;  // ... from a geometry strong enough to be a match
      if (comparison.geometry.success) {
        step.heading = PlanarHeading(comparison.geometry.b_from_a);
        const bool behind = std::abs(*step.heading) > M_PI / 2;
        // A subgoal behind that still matches was passed before its successor matched. A heading behind from a
        // weaker geometry (a few chance inliers point anywhere) is no evidence: moving on from it skipped whole
        // stretches of the path in the simulated town. Either would turn the robot round.
        reached = behind && comparison.matches;
        if (!behind) heading = step.heading;
      } else {
        // The subgoal's own place: it matches, but the matches show no parallax.
        reached = comparison.matches && comparison.geometry.failure == TwoViewFailure::kInsufficientParallax;
      }
      if (reached && is_goal) {
        at_goal_ = true;
      } else if (reached) {
        // On the way to the next key-image of the shortest path.
        if (const auto onwards = paths_to_goal_.next.find(subgoal_); onwards != paths_to_goal_.next.end()) {
          previous_ = subgoal_;
          subgoal_ = step.subgoal = onwards->second.to;
          ++step.advanced;
          heading.reset();
          step.heading.reset();
          const Comparison next = Compare(subgoal_, &step.compared);
          heading_matches = next.matches;
          if (next.geometry.success) {
            step.heading = PlanarHeading(next.geometry.b_from_a);
            if (std::abs(*step.heading) <= M_PI / 2) heading = step.heading;
          }
          step.similarity = comparisons_.at(subgoal_).similarity;
        }
      }
      // A subgoal that gives no heading of its own, or only from a geometry too weak to be a match (a turn: the
      // subgoal is round a corner, beside or behind the robot; a few chance inliers then point anywhere, often
      // straight on): the direction of the taught arc to it from the previous subgoal, if that one matches.
      if (!(heading && heading_matches) && !at_goal_ && previous_ != kInvalidNodeId) {
        const Comparison anchor = Compare(previous_, &step.compared);
        const std::optional<double> along =
            anchor.matches && anchor.geometry.success
                ? HeadingAlongArc(map(), previous_, subgoal_, anchor.geometry.b_from_a.rotation,
                                  camera_mount_.level_from_camera)
                : std::nullopt;
        if (along) {
          heading = step.heading = along;
          step.along_arc = true;
        }
      }
      filter_.Update(heading);
      if (at_goal_) step.state = NavigationState::kAtGoal;
    }
  }

  step.misses = filter_.misses();
  step.filtered_heading = filter_.heading();
  if (const auto d = paths_to_goal_.distance.find(subgoal_); d != paths_to_goal_.distance.end()) {
    step.distance_to_goal = d->second;
  }
  if (step.state == NavigationState::kNavigating && image_steering.has_value()) {
    // On a taught arc of the plan: Segvic 2009 eq. (10), w < 0 turns left (curvature positive left), limited to the
    // sharpest turn the heading law commands (2 / ℓ: a point beside the robot).
    const double max_curvature = 2.0 / options_.look_ahead;
    step.curvature = std::clamp(-options_.image_steering_gain * *image_steering, -max_curvature, max_curvature);
    step.speed = options_.speed;
    step.image_steering = true;
  } else if (step.state == NavigationState::kNavigating && step.filtered_heading.has_value()) {
    step.curvature = Curvature(*step.filtered_heading);
    step.speed = step.heading.has_value() ? options_.speed : 0.5 * options_.speed;
  }
  step.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return step;
}

}  // namespace retrace
