#pragma once

// Navigation to a goal on the appearance graph (Booij et al. 2007, §B.4; design §7): the robot drives towards one
// key-image at a time, chosen while driving, by the heading of the planar two-view geometry between its current
// image and that key-image.
//
//   first image ──> localization: the key-image of highest similarity S (all key-images, as the paper; or the
//                   closest `localization_candidates` in appearance) becomes the subgoal c
//   every image ──> subgoal: AdvanceSubgoal (subgoal.h): c ← the neighbour nearest the goal that still matches
//               ──> heading φ to c: planar essential (geometry/planar_pose.h, eq. B.4) whenever the matches give
//                   one (the paper's heading fails only for too few correspondences), smoothed by HeadingFilter
//               ──> curvature towards φ̂ (pure pursuit, Coulter 1992: κ = 2 sin φ̂ / ℓ), speed
//   10 images in a row without a heading ──> relocalize (localization again, the filter forgotten)
//   c = goal and the goal is passed (its heading more than 90° off ahead) or reached (no parallax left) ──> stop
//
// A key-image "matches" the current image when wide-baseline matching (feature/wide_baseline.h) and a planar
// geometry verified on the matches give a similarity S ≥ min_similarity: the graph's own link criterion (Booij 2007
// §B.2, S = epipolar-consistent matches over the fewer key-points of the two images; teach's min_join_similarity).
//
// Two guards follow from the geometry rather than from tuning. A heading more than 90° from ahead towards a subgoal
// that still matches means the robot has passed it before its successor matched: that heading would turn the robot
// round, so it counts as no heading (the robot drives on with the filtered one) and the subgoal becomes the next
// key-image of the shortest path from it (the robot is past c, so on its way to that one); the same when the
// subgoal matches without parallax (the robot is at its place). And at the goal, the paper's "stop when the subgoal
// is the goal" would stop where the goal first matches, possibly tens of metres before it with a panoramic camera:
// the robot drives on until the goal, matching, is more than 90° off ahead (beside or behind) or shows no parallax.
// A heading behind from a geometry too weak to be a match (a few chance inliers point anywhere) is only ignored.
// When the subgoal n gives no heading of its own, or one from a geometry too weak to be a match — at a turn n is
// round the corner, beside or behind the robot, seen across 90° under another light, and a few chance inliers
// point anywhere, often straight on — the robot heads along the taught arc from the previous subgoal c to n, if c
// still matches: the arc's direction in c's frame (the map) turned into the robot's frame by the rotation of the
// current geometry to c (the robot's few metres from c neglected against the arc's length).
//
// Beneath it runs the localizer of repeat (Segvic 2009, repeat/localizer.h; NavigatorOptions::follow_taught_arcs),
// fed every image. Its belief is told the plan's arcs, so that at a junction it expects the branch the plan chose
// (PlaceBelief::SetPlannedArcs). Where it tracks an arc between two places of the plan (key-images of the plan or
// linked to them) whose taught direction is the plan's (a driven arc, not a link), the robot steers by the image as
// in repeat (eq. (10): κ = −g · w) instead of by the heading, and so keeps to the taught line between key-images.
// Where it tracks, confidently, an arc none of whose key-images is a place of the plan (a key-image of it, or one
// linked to such by a join or loop: where drives overlap, the localizer may follow either), the robot took another
// branch (it takes one arc to tell that from an overshoot at a junction, whose first arc still starts on the plan):
// the navigator replans from that arc's end (its key-image becomes the subgoal, the shortest path from it the plan).
//
// Bearings are rotated into the level frame of the ground plane estimated from the map's arcs (camera_mount.h), so
// that the planar model holds for a camera pitched against the ground (a car's camera) across turns.
//
// The camera frame is retrace's (x right, y down, z forward); the robot drives along z. Headings: 0 ahead,
// positive right (PlanarHeading). Curvature: positive left (the simulator's and the path tracker's convention).

#include <list>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include <opencv2/core.hpp>

#include "retrace/camera/camera_model.h"
#include "retrace/control/path_tracking.h"
#include "retrace/feature/global_descriptor.h"
#include "retrace/feature/wide_baseline.h"
#include "retrace/geometry/two_view_geometry.h"
#include "retrace/map/map.h"
#include "retrace/nav/graph_planner.h"
#include "retrace/nav/camera_mount.h"
#include "retrace/nav/heading_filter.h"
#include "retrace/nav/subgoal.h"
#include "retrace/repeat/localizer.h"

namespace retrace {

// The navigator's default matching (see NavigatorOptions::matching).
WideBaselineOptions NavigationMatchingDefaults();

// The heading (as PlanarHeading: radians, 0 ahead, positive right) from the robot to key-image `to` along the
// taught arc between key-images `from` and `to` (either direction): `to`'s centre in `from`'s frame, levelled by
// `level_from_camera`, turned into the robot's frame by the rotation `from_from_robot` (x_from = R x_robot + t, in
// the level frames) of the robot's geometry to `from`. Exact when the robot stands at `from`; the robot's offset
// from it is neglected. Empty when no arc links the two.
std::optional<double> HeadingAlongArc(const Map& map, node_t from, node_t to, const Matrix3d& from_from_robot,
                                      const Matrix3d& level_from_camera);

struct NavigatorOptions {
  // The graph and its edge lengths (graph_planner.h). A panoramic camera sees a route backwards as well as forwards
  // (directed = false, the paper's setting); a forward-looking camera should plan along the taught directions.
  PlanOptions planning;
  HeadingFilterOptions heading;
  // Key-points and matches between the image and a key-image: SIFT (difference of Gaussians) alone, as Booij 2007
  // (the similarity S counts over the key-points, so more detectors of weaker repeatability lower S for the same
  // place), and Lowe's ratio 0.8 (the planar geometry verifies the matches). On the simulated panoramic town under
  // another sun this keeps S ≥ 0.05 to about 5 m from a key-image (0.6 and all detectors: 1 m).
  WideBaselineOptions matching = NavigationMatchingDefaults();
  // The planar two-view geometry between the current image and a key-image (min_inliers: the paper's 3-4 points
  // are the minimum; 8 by default, as everywhere in retrace).
  TwoViewOptions geometry;
  // A key-image matches the current image when the similarity S reaches this (Booij 2007 §B.2: 0.05).
  double min_similarity = 0.05;
  // Localization compares the image with every key-image (0, the paper's linear search) or with this many of them,
  // the closest in appearance first (global_descriptor.h).
  int localization_candidates = 0;
  // Pure pursuit: distance (m) to the point the robot steers towards, in the subgoal's direction. Larger is
  // smoother, smaller follows the subgoals' headings more tightly.
  double look_ahead = 5.0;
  // Speed (m/s) while a heading is known; half of it while driving on the filtered heading without a new one, 0
  // while (re)localizing and at the goal.
  double speed = 2.0;
  // Features of this many key-images are kept between images (a subgoal's neighbourhood needs a handful).
  int max_cached_key_images = 64;
  // Rotate every bearing into the level frame of the ground plane estimated from the map's arcs (camera_mount.h)
  // before the planar geometry, so that a camera pitched or rolled against the ground still moves in the plane the
  // model assumes. Off: the camera is taken as level (Booij's upright panoramic camera).
  bool level_camera = true;
  CameraMountOptions camera_mount;
  // Run the Segvic localizer beneath (see above): image steering on the plan's taught arcs, the belief following the
  // plan's branch, replanning when it tracks off the plan. Off: the heading alone steers (Booij 2007).
  bool follow_taught_arcs = true;
  // Its options; the tracking settings must be teach's (LoadMapForLocalizer reads them from the map).
  LocalizerOptions localizer;
  // g of κ = −g · w, eq. (10)'s w (radians) turned into a curvature (1/m): the path tracker's fallback gain
  // (PathTrackingOptions::image_gain, which reproduces front wheels at −w on a car of 2.7 m wheelbase).
  double image_steering_gain = PathTrackingOptions().image_gain;

  bool Check(std::string* error = nullptr) const;
};

enum class NavigationState {
  kLocalizing,  // no key-image matches the image yet: standing still
  kNavigating,  // driving towards the subgoal
  kAtGoal,      // stopped at the goal
  kNoPath,      // the goal cannot be reached from the key-image the robot is at: standing still
};

const char* NavigationStateName(NavigationState state);

// What the navigator did with one image.
struct NavigationStep {
  NavigationState state = NavigationState::kLocalizing;
  node_t subgoal = kInvalidNodeId;
  int advanced = 0;              // steps the subgoal moved towards the goal with this image
  bool relocalized = false;      // this image (re)localized the robot
  int compared = 0;              // key-images compared with this image
  std::optional<double> heading;           // to the subgoal from this image (radians, positive right)
  bool along_arc = false;        // the heading is the taught arc's from the subgoal just passed (round a turn)
  std::optional<double> filtered_heading;  // the recency-weighted heading the robot steers by
  double similarity = 0.0;       // of the image and the subgoal (0 without a geometry)
  int misses = 0;                // images in a row without a heading
  double curvature = 0.0;        // steering command (1/m, positive left)
  double speed = 0.0;            // speed command (m/s)
  double distance_to_goal = 0.0;  // D of the subgoal (graph units of the plan's cost)
  // The localizer beneath (follow_taught_arcs): its state, the arc it tracks (invalid unless tracking), and what the
  // navigator made of it.
  LocalizerState localizer_state = LocalizerState::kRelocalizing;
  arc_t arc = kInvalidArcId;
  double localizer_confidence = 0.0;
  bool on_plan = false;         // the arc runs between places of the plan, in the plan's direction
  bool image_steering = false;  // the curvature is eq. (10)'s (else the heading's)
  bool replanned = false;       // the arc was off the plan: planned again from its end
  double seconds = 0.0;          // processing time of this image
};

class Navigator {
 public:
  // Navigates in `map` (key-images readable: loaded or through Map::KeyImage) with images of `camera` (the camera
  // of the key-images) towards `goal`. Throws std::invalid_argument for bad options, a goal not in the map, or a
  // map the plan's cost cannot use (BuildPlanningGraph).
  Navigator(Map map, const CameraModel& camera, node_t goal, const NavigatorOptions& options = {});

  // One camera image (8-bit gray, the key-images' size): the subgoal, heading and command.
  NavigationStep ProcessImage(const cv::Mat& image);

  // The map (held by the localizer beneath when there is one).
  const Map& map() const { return localizer_ ? localizer_->map() : map_; }
  node_t goal() const { return goal_; }
  node_t subgoal() const { return subgoal_; }
  // The path planned to the goal from the key-image of the last (re)localization.
  const PlannedPath& planned_path() const { return planned_path_; }
  int relocalizations() const { return relocalizations_; }
  // Plans made again because the localizer tracked an arc off the plan.
  int replans() const { return replans_; }
  // The ground plane the bearings are levelled by (a level camera when options.level_camera is off).
  const CameraMount& camera_mount() const { return camera_mount_; }
  // D of every node that reaches the goal.
  const std::unordered_map<node_t, double>& distances_to_goal() const { return paths_to_goal_.distance; }

 private:
  struct KeyImageFeatures {
    WideBaselineFeatures features;
    std::vector<Vector3d> bearings;  // per key-point; zero when the camera gives no ray
  };
  struct Comparison {
    TwoViewGeometry geometry;  // b_from_a: the key-image's frame from the current image's
    double similarity = 0.0;
    bool matches = false;
  };

  const KeyImageFeatures& FeaturesOf(node_t node);
  KeyImageFeatures Describe(const cv::Mat& image) const;
  Comparison Compare(node_t node, int* compared);
  // The key-image that matches the current image best (kInvalidNodeId when none does).
  node_t Localize(int* compared);
  double Curvature(double heading) const;
  // The localizer's view of this image: on the plan or off it (and then replans). Fills the step's localizer fields;
  // returns eq. (10)'s w when the robot is to steer by the image.
  std::optional<double> FollowLocalizer(const cv::Mat& image, NavigationStep* step);
  // The plan from `start` (PathFromTree), told to the localizer's belief.
  void SetPlan(node_t start);

  Map map_;  // moved into the localizer when there is one: read through map()
  std::unique_ptr<CameraModel> camera_;
  node_t goal_;
  NavigatorOptions options_;
  CameraMount camera_mount_;
  PlanningGraph graph_;
  ShortestPathTree paths_to_goal_;  // Dijkstra towards the goal, once: D and the next node of every shortest path
  PlannedPath planned_path_;
  // Its key-images and those linked to them (join, loop), with the position along it of the key-image of the plan.
  std::unordered_map<node_t, size_t> planned_places_;
  HeadingFilter filter_;

  node_t subgoal_ = kInvalidNodeId;
  node_t previous_ = kInvalidNodeId;  // the subgoal before the current one (its arc to it gives a heading)
  bool at_goal_ = false;
  int relocalizations_ = 0;
  int replans_ = 0;
  std::unique_ptr<Localizer> localizer_;  // follow_taught_arcs
  size_t frames_ = 0;

  cv::Mat current_image_;     // the image being processed
  KeyImageFeatures current_;  // its features
  std::unordered_map<node_t, Comparison> comparisons_;  // of the current image, by key-image
  std::unordered_map<node_t, KeyImageFeatures> cache_;
  std::unique_ptr<AppearanceIndex> appearance_index_;  // of every node in map_.nodes() order (localization_candidates)
  std::list<node_t> cache_order_;  // most recently used first
};

}  // namespace retrace
