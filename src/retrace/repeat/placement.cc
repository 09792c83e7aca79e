#include "retrace/repeat/placement.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <string>

#include "retrace/geometry/triangulation.h"
#include "retrace/util/robust_random_walk.h"

namespace retrace {

Vector3d CameraCentre(const Rigid3d& cam_from_world) {
  return -cam_from_world.rotation.transpose() * cam_from_world.translation;
}

namespace {

// The arc's unit direction of travel in its own frame (a at the origin): C_b / |C_b|.
Vector3d ArcDirection(const Rigid3d& arc_b_from_a) { return CameraCentre(arc_b_from_a).normalized(); }

// A bound's normal, or the arc's direction where the bound keeps the perpendicular plane.
Vector3d NormalOr(const Vector3d& normal, const Vector3d& direction) {
  return normal.squaredNorm() > 0 ? normal : direction;
}

// Between the planes, s_a − s_b below this (arc lengths): the camera is near where the two planes meet, about a turn
// radius beside the route, and `along` between them means nothing there.
constexpr double kMinPlaneSeparation = 0.25;

// `along` of the camera centre `c_t` on the arc from the origin to `c_b` (arc frame) bounded by `bounds`, and its
// gradient with respect to `c_t` (header: between the planes s_a / (s_a − s_b); before a's plane and past b's the
// distance from that plane along the arc, s / (d · n), which continues the arc's own scale; beyond where the planes
// meet, or with them, the chord projection).
struct AlongAndGradient {
  double along = 0.0;
  Vector3d gradient = Vector3d::Zero();
};
AlongAndGradient AlongBetweenPlanes(const Vector3d& c_t, const Vector3d& c_b, const ArcBounds& bounds) {
  const double length = c_b.norm();
  const Vector3d direction = c_b / length;
  const Vector3d n_a = NormalOr(bounds.normal_at_from, direction);
  const Vector3d n_b = NormalOr(bounds.normal_at_to, direction);
  const double s_a = c_t.dot(n_a) / length;
  const double s_b = (c_t - c_b).dot(n_b) / length;
  if (s_a >= 0.0 && s_b <= 0.0 && s_a - s_b >= kMinPlaneSeparation) {
    const double separation = s_a - s_b;
    return {s_a / separation, (s_a * n_b - s_b * n_a) / (separation * separation * length)};
  }
  if (s_a >= 0.0 && s_b > 0.0) {
    const double cosine = direction.dot(n_b);
    return {1.0 + s_b / cosine, n_b / (cosine * length)};
  }
  if (s_a < 0.0 && s_b <= 0.0) {
    const double cosine = direction.dot(n_a);
    return {s_a / cosine, n_a / (cosine * length)};
  }
  return {c_t.dot(direction) / length, direction / length};
}

}  // namespace

ArcBounds BisectingBounds(const Rigid3d& arc_b_from_a, const Rigid3d* previous_a_from_z, const Rigid3d* next_c_from_b,
                          double max_turn_deg) {
  ArcBounds bounds;
  const Vector3d direction = ArcDirection(arc_b_from_a);
  if (!direction.allFinite()) return bounds;
  const double min_cosine = std::cos(max_turn_deg * M_PI / 180.0);
  const auto bisect = [&](const Vector3d& other) -> Vector3d {
    // The normal of the plane equidistant from the two arcs' lines through their common node.
    if (!other.allFinite() || other.dot(direction) < min_cosine) return Vector3d::Zero();
    return (other + direction).normalized();
  };
  if (previous_a_from_z != nullptr) {
    // Direction z -> a in z's frame is C_a = -Rᵀt; in a's frame R C_a = -t.
    bounds.normal_at_from = bisect(-previous_a_from_z->translation.normalized());
  }
  if (next_c_from_b != nullptr) {
    // Direction b -> c in b's frame is C_c = -R_qᵀ t_q; in a's frame R_kᵀ C_c.
    bounds.normal_at_to = bisect(arc_b_from_a.rotation.transpose() * CameraCentre(*next_c_from_b).normalized());
  }
  return bounds;
}

ArcPosition LocateOnArc(const Rigid3d& current_from_a, const Rigid3d& arc_b_from_a, const ArcBounds& bounds) {
  ArcPosition position;
  const Vector3d c_t = CameraCentre(current_from_a);
  const Vector3d c_b = CameraCentre(arc_b_from_a);
  const double length_sq = c_b.squaredNorm();
  if (!c_t.allFinite() || !(length_sq > 0)) return position;
  position.valid = true;
  const double length = std::sqrt(length_sq);
  position.along = AlongBetweenPlanes(c_t, c_b, bounds).along;
  position.distance_to_from = c_t.norm() / length;
  position.distance_to_to = (c_t - c_b).norm() / length;
  return position;
}

bool InFrontOfStartPlane(const Vector3d& centre, const Rigid3d& arc_b_from_a, const ArcBounds& bounds) {
  return centre.dot(NormalOr(bounds.normal_at_from, ArcDirection(arc_b_from_a))) >= 0.0;
}

ArcPosition AlongArc(double along) {
  ArcPosition position;
  position.valid = std::isfinite(along);
  position.along = along;
  position.distance_to_from = std::abs(along);
  position.distance_to_to = std::abs(1.0 - along);
  return position;
}

ResumptionPolicy DecideResumption(const ArcPosition& position, double next_arc_ratio, double previous_arc_ratio) {
  ResumptionPolicy policy;
  if (!position.valid) return policy;
  policy.next = position.distance_to_to < next_arc_ratio;            // Segvic 2009, eq. (7)
  policy.previous = position.distance_to_from < previous_arc_ratio;  // Segvic 2009, eq. (8)
  return policy;
}

bool GeometryUsable(const TwoViewGeometry& geometry, double max_sigma_p_px) {
  return geometry.success && geometry.sigma_p < max_sigma_p_px;
}

int DecideTransition(const ArcPosition& position, double backward_margin) {
  if (!position.valid) return 0;
  // Segvic 2009, eq. (9). With the camera centre C_t in the arc's frame (a at the origin, b at C_b), the plane
  // through C_b that ends the arc (normal n_b) is passed when s_b = (C_t - C_b) . n_b > 0, i.e. along > 1 (for the
  // paper's plane, n_b = C_b / |C_b|: along = C_t . C_b / |C_b|^2 > 1).
  if (position.along > 1.0) return +1;
  if (position.along < -backward_margin) return -1;
  return 0;
}

double AlongSigma(const Matrix3d& centre_covariance, const Rigid3d& arc_b_from_a, const Vector3d& centre,
                  const ArcBounds& bounds) {
  const Vector3d c_b = CameraCentre(arc_b_from_a);
  const double length_sq = c_b.squaredNorm();
  if (!(length_sq > 0)) return std::numeric_limits<double>::infinity();
  const Vector3d gradient = AlongBetweenPlanes(centre, c_b, bounds).gradient;
  const double variance = gradient.dot(centre_covariance * gradient);
  return variance >= 0 ? std::sqrt(variance) : std::numeric_limits<double>::infinity();
}

AbsolutePose ResectFromKeyImages(const std::vector<KeyImageMatches>& views, double max_angle_rad,
                                 double focal_length_px, const AbsolutePoseOptions& options, int* num_points) {
  // The frame's key-points matched in two or more key-images: (view, match) per key-point.
  std::map<int, std::vector<std::pair<size_t, size_t>>> seen_in;
  for (size_t v = 0; v < views.size(); ++v) {
    for (size_t m = 0; m < views[v].current_keypoints.size(); ++m) {
      seen_in[views[v].current_keypoints[m]].push_back({v, m});
    }
  }
  std::vector<Vector3d> points, bearings;
  std::vector<Matrix3d> covariances;
  for (const auto& [keypoint, matches] : seen_in) {
    double widest = 0.0;  // sine of the angle between the two rays
    std::optional<std::pair<Vector3d, Matrix3d>> best;
    for (size_t i = 0; i < matches.size(); ++i) {
      for (size_t j = i + 1; j < matches.size(); ++j) {
        const KeyImageMatches& first = views[matches[i].first];
        const KeyImageMatches& second = views[matches[j].first];
        const Rigid3d second_from_first = second.key_from_arc * first.key_from_arc.Inverse();
        TriangulatedPoint triangulated;
        if (!TriangulateMidpoint(second_from_first, first.key_bearings[matches[i].second],
                                 second.key_bearings[matches[j].second], &triangulated) ||
            !(triangulated.depth_a > 0) || !(triangulated.depth_b > 0)) {
          continue;
        }
        const Vector3d centre_second = CameraCentre(second_from_first);
        const double angle =
            triangulated.point_in_a.normalized().cross((triangulated.point_in_a - centre_second).normalized()).norm();
        if (!(angle > widest)) continue;
        const Rigid3d arc_from_first = first.key_from_arc.Inverse();
        const Vector3d in_arc = arc_from_first * triangulated.point_in_a;
        bool consistent = true;
        for (const auto& [v, m] : matches) {
          const Vector3d in_key = views[v].key_from_arc * in_arc;
          const Vector3d& ray = views[v].key_bearings[m];
          consistent &= in_key.dot(ray) > 0 && in_key.normalized().cross(ray).norm() < max_angle_rad;
        }
        if (!consistent) continue;
        widest = angle;
        const Matrix3d& rotation = arc_from_first.rotation;
        best = std::make_pair(
            in_arc,
            Matrix3d(rotation * TwoViewPointCovariance(triangulated.point_in_a, centre_second) * rotation.transpose()));
      }
    }
    if (!best) continue;
    const auto& [v, m] = matches.front();
    points.push_back(best->first);
    bearings.push_back(views[v].current_bearings[m]);
    covariances.push_back(best->second);
  }
  if (num_points != nullptr) *num_points = static_cast<int>(points.size());
  return EstimateAbsolutePose(points, bearings, focal_length_px, options, &covariances);
}

bool PlacementModel::Check(std::string* error) const {
  const auto fail = [&](const std::string& message) {
    if (error != nullptr) *error = message;
    return false;
  };
  if (!(pose_sigma_floor > 0) || !(geometry_sigma > 0) || !(key_image_sigma > 0)) {
    return fail("placement sigmas must be positive");
  }
  if (!(geometry_extrapolation_length > 0)) return fail("geometry_extrapolation_length must be positive");
  if (!(geometry_distance_length >= 0)) return fail("geometry_distance_length must be >= 0 (0: off)");
  if (!(pose_shared_error_px >= 0)) return fail("pose_shared_error_px must be >= 0");
  if (!(pose_height_sigma >= 0)) return fail("pose_height_sigma must be >= 0");
  if (!(key_image_beside_sigma >= 0)) return fail("key_image_beside_sigma must be >= 0");
  if (!(pose_height_outlier_span > 0)) return fail("pose_height_outlier_span must be positive");
  if (!(pose_lateral_sigma >= 0)) return fail("pose_lateral_sigma must be >= 0");
  if (!(lane_heading_sigma > 0) || !(lane_window > 0)) {
    return fail("lane_heading_sigma and lane_window must be positive");
  }
  if (!(pose_collapse_probability > 0) || !(pose_collapse_probability < 1)) {
    return fail("pose_collapse_probability must be in (0, 1)");
  }
  if (!(collapsed_pose_sigma >= 0)) return fail("collapsed_pose_sigma must be >= 0");
  if (!(lane_outlier_probability > 0) || !(lane_outlier_probability < 1) || !(lane_outlier_span > 0)) {
    return fail("lane_outlier_probability must be in (0, 1) and lane_outlier_span positive");
  }
  if (lane_max_poses < 2 || lane_max_arcs < 1) return fail("lane_max_poses must be >= 2 and lane_max_arcs >= 1");
  if (!(verified_pose_sigma_factor >= 1) || !(verified_pose_sigma_floor > 0)) {
    return fail("verified_pose_sigma_factor must be >= 1 and verified_pose_sigma_floor positive");
  }
  if (!(pose_outlier_inliers >= 0)) return fail("pose_outlier_inliers must be >= 0");
  if (!(pose_outlier_min > 0) || !(pose_outlier_min <= pose_outlier_max)) {
    return fail("pose_outlier_min must be positive and at most pose_outlier_max");
  }
  for (const double p : {pose_outlier_probability, pose_outlier_max, geometry_outlier_probability,
                         key_image_outlier_probability, verified_pose_outlier_probability}) {
    if (!(p > 0) || !(p < 1)) return fail("placement outlier probabilities must be in (0, 1)");
  }
  return true;
}

PoseSpread SpreadOfInliers(const AbsolutePose& pose, const std::vector<Vector3d>& points_in_world,
                           const std::vector<Vector3d>& bearings, double arc_length, double focal_length_px) {
  std::vector<double> depths;
  double sum_squares = 0.0;
  for (size_t i = 0; i < points_in_world.size() && i < pose.inlier_mask.size() && i < bearings.size(); ++i) {
    if (!pose.inlier_mask[i]) continue;
    depths.push_back((pose.cam_from_world * points_in_world[i]).norm());
    // The angle from the optical axis (any camera model): a relative scale change δs of the image moves it by δs.
    const double angle = std::atan2(bearings[i].head<2>().norm(), bearings[i].z());
    sum_squares += angle * angle;
  }
  PoseSpread spread;
  if (depths.empty() || !(arc_length > 0)) return spread;
  std::nth_element(depths.begin(), depths.begin() + depths.size() / 2, depths.end());
  spread.median_depth = depths[depths.size() / 2] / arc_length;
  spread.rms_radius_px = focal_length_px * std::sqrt(sum_squares / depths.size());
  return spread;
}

Vector3d GroundNormalOfArc(const Rigid3d& arc_b_from_a) {
  // The ground plane holds the direction of travel and the camera's x axis (no roll): its normal is their cross
  // product, turned to point down (+y). Travelling along x itself (a quarter turn within one arc), the down axis made
  // perpendicular to the travel.
  const Vector3d direction = ArcDirection(arc_b_from_a);
  const Vector3d normal = Vector3d::UnitX().cross(direction);
  if (normal.norm() < 0.1) {
    return (Vector3d::UnitY() - direction.y() * direction).normalized();
  }
  return normal.y() >= 0.0 ? normal.normalized() : Vector3d(-normal.normalized());
}

namespace {

// How far the camera centre lies from the chord C_a C_b along the unit `direction` (arc lengths), with its σ from the
// pose's covariance: δ = u · (C_t − t C_b) with t = C_t · C_b / |C_b|² the centre's projection on the chord; its
// gradient in C_t is u − (u · C_b) C_b / |C_b|².
PoseDeviation OffChord(const AbsolutePose& pose, const Rigid3d& arc_b_from_a, const Vector3d& direction) {
  PoseDeviation off;
  const Vector3d c_b = CameraCentre(arc_b_from_a);
  const double length_sq = c_b.squaredNorm();
  if (!pose.covariance_valid || !(length_sq > 0) || !direction.allFinite() || !(direction.norm() > 0)) return off;
  const double length = std::sqrt(length_sq);
  const Vector3d u = direction.normalized();
  const Vector3d c_t = CameraCentre(pose.cam_from_world);
  const double t = c_t.dot(c_b) / length_sq;
  const Vector3d gradient = u - u.dot(c_b) / length_sq * c_b;
  const double variance = gradient.dot(pose.centre_covariance * gradient);
  if (!std::isfinite(t) || !(variance >= 0)) return off;
  off.valid = true;
  off.deviation = u.dot(c_t - t * c_b) / length;
  off.sigma = std::sqrt(variance) / length;
  return off;
}

}  // namespace

PoseDeviation HeightOffArc(const AbsolutePose& pose, const Rigid3d& arc_b_from_a, const Vector3d& ground_normal) {
  return OffChord(pose, arc_b_from_a, ground_normal);
}

PoseDeviation HeightOffArc(const AbsolutePose& pose, const Rigid3d& arc_b_from_a) {
  return HeightOffArc(pose, arc_b_from_a, GroundNormalOfArc(arc_b_from_a));
}

PoseDeviation LateralOffArc(const AbsolutePose& pose, const Rigid3d& arc_b_from_a) {
  // The side axis: perpendicular to the ground's normal (down) and to the chord, pointing right (down × forward).
  return OffChord(pose, arc_b_from_a, GroundNormalOfArc(arc_b_from_a).cross(ArcDirection(arc_b_from_a)));
}

double HeadingOffArc(const Rigid3d& current_from_a, const Rigid3d& arc_b_from_a, double along) {
  const Vector3d n = GroundNormalOfArc(arc_b_from_a);
  // The signed angle from key-image a's optical axis to `forward` about the normal (down: positive to the right),
  // both on the ground plane.
  const auto yaw = [&n](const Vector3d& forward) {
    const Vector3d on_ground = forward - forward.dot(n) * n;
    const Vector3d axis = Vector3d::UnitZ() - n.z() * n;
    return std::atan2(n.dot(axis.cross(on_ground)), axis.dot(on_ground));
  };
  const Vector3d current = current_from_a.rotation.transpose() * Vector3d::UnitZ();
  const Vector3d at_b = arc_b_from_a.rotation.transpose() * Vector3d::UnitZ();
  const double heading = yaw(current) - along * yaw(at_b);
  return std::isfinite(heading) ? std::remainder(heading, 2.0 * M_PI) : 0.0;
}

PoseDeviation LanePrediction(const std::vector<LaneObservation>& observations, double arc_length,
                             const PlacementModel& model) {
  PoseDeviation prediction;
  if (observations.size() < 2 || !(arc_length > 0)) return prediction;
  std::vector<CarriedObservation> carried;
  carried.reserve(observations.size());
  for (const LaneObservation& o : observations) {
    const double drift = model.lane_heading_sigma * std::abs(o.travelled);
    carried.push_back({o.lateral + std::sin(o.heading) * o.travelled, std::max(o.sigma, 1e-6), drift * drift, -1});
  }
  const CombinedObservation combined =
      CombineCarriedObservations(carried, model.lane_outlier_probability, model.lane_outlier_span * arc_length);
  if (!combined.valid || combined.inliers < 2) return prediction;
  prediction.valid = true;
  prediction.deviation = combined.value;
  prediction.sigma = combined.sigma;
  return prediction;
}

namespace {

double GaussianDensity(double deviation, double variance) {
  return std::exp(-0.5 * deviation * deviation / variance) / std::sqrt(2.0 * M_PI * variance);
}

}  // namespace

double CollapseProbability(const LaneCheck& lane, const PlacementModel& model) {
  if (!lane.valid || !(model.pose_lateral_sigma > 0)) return 0.0;
  // On the lane: Gaussian around the prediction. Collapsed: uniform over the offsets no farther from the path than
  // the lane, on either side of it, widened by two σ.
  const double variance = lane.sigma * lane.sigma + model.pose_lateral_sigma * model.pose_lateral_sigma;
  const double half_width = std::abs(lane.predicted) + 2.0 * std::sqrt(variance);
  if (!(std::abs(lane.lateral) <= half_width)) return 0.0;
  const double on_lane =
      (1.0 - model.pose_collapse_probability) * GaussianDensity(lane.lateral - lane.predicted, variance);
  const double collapsed = model.pose_collapse_probability * 0.5 / half_width;
  const double posterior = collapsed / (collapsed + on_lane);
  return std::isfinite(posterior) ? posterior : 0.0;
}

double FarSideProbability(const LaneCheck& lane, const PlacementModel& model) {
  if (!lane.valid || !(model.pose_lateral_sigma > 0) || !(lane.lateral * lane.predicted < 0)) return 0.0;
  const double variance = lane.sigma * lane.sigma + model.pose_lateral_sigma * model.pose_lateral_sigma;
  // Farther out than the lane: the lane may rest on poses that crossed the path (as in CollapseProbability, a pose
  // farther out than the lane is not doubted).
  if (std::abs(lane.lateral) > std::abs(lane.predicted) + 2.0 * std::sqrt(variance)) return 0.0;
  const double c = model.pose_collapse_probability;
  const double on_lane = (1.0 - c) * GaussianDensity(lane.lateral - lane.predicted, variance);
  // Collapsed onto the path, where such poses pile up, with the check's noise.
  const double collapsed = c * GaussianDensity(lane.lateral, variance);
  const double wrong = model.pose_outlier_probability / model.lane_outlier_span;
  const double posterior = wrong / (wrong + (1.0 - model.pose_outlier_probability) * (on_lane + collapsed));
  return std::isfinite(posterior) ? posterior : 0.0;
}

double PoseOutlierProbability(int inliers, const PlacementModel& model) {
  if (!(model.pose_outlier_inliers > 0)) return model.pose_outlier_probability;
  const double ratio = model.pose_outlier_inliers / std::max(inliers, 1);
  return std::clamp(model.pose_outlier_probability * ratio * ratio, model.pose_outlier_min, model.pose_outlier_max);
}

PlaceMeasurement PoseMeasurement(arc_t arc, const ArcPosition& position, const AbsolutePose& pose,
                                 const Rigid3d& arc_b_from_a, const PlacementModel& model, const ArcBounds& bounds,
                                 const PoseSpread& spread, const PoseDeviation& height, double collapse_probability,
                                 double far_side_probability) {
  double sigma = model.pose_sigma_floor;
  if (pose.covariance_valid) {
    const double fitted = AlongSigma(pose.centre_covariance, arc_b_from_a, CameraCentre(pose.cam_from_world), bounds);
    sigma = std::isfinite(fitted) ? std::hypot(fitted, model.pose_sigma_floor) : 1.0;
  }
  if (spread.median_depth > 0 && spread.rms_radius_px > 0) {
    sigma = std::hypot(sigma, model.pose_shared_error_px / spread.rms_radius_px * spread.median_depth);
  }
  // Bayes' rule on the centre's height off the arc (PlacementModel::pose_height_sigma): the pose a wrong one with the
  // prior probability, its height uniform over the span then; raised only (a height on the line does not confirm a
  // pose, which can be wrong along the road).
  double outlier_probability = PoseOutlierProbability(pose.num_inliers, model);
  if (height.valid && model.pose_height_sigma > 0) {
    const double variance = height.sigma * height.sigma + model.pose_height_sigma * model.pose_height_sigma;
    const double right = GaussianDensity(height.deviation, variance);
    const double wrong = 1.0 / model.pose_height_outlier_span;
    const double posterior =
        outlier_probability * wrong / (outlier_probability * wrong + (1.0 - outlier_probability) * right);
    if (std::isfinite(posterior)) outlier_probability = std::max(outlier_probability, posterior);
  }
  outlier_probability = std::max(outlier_probability, far_side_probability);
  // The probability that the pose collapsed towards the path (CollapseProbability) widens its σ.
  if (collapse_probability > 0) {
    sigma = std::sqrt(sigma * sigma + collapse_probability * model.collapsed_pose_sigma * model.collapsed_pose_sigma);
  }
  // Kept below 1: a measurement that is certainly an outlier carries no information but must not zero the belief.
  return {arc, position.along, sigma, std::min(outlier_probability, 0.999)};
}

PlaceMeasurement VerifiedPoseMeasurement(arc_t arc, const ArcPosition& position, const AbsolutePose& pose,
                                         const Rigid3d& arc_b_from_a, const PlacementModel& model,
                                         const ArcBounds& bounds) {
  PlaceMeasurement placed =
      PoseMeasurement(arc, position, pose, arc_b_from_a, model, bounds, PoseSpread(), HeightOffArc(pose, arc_b_from_a));
  placed.sigma = std::hypot(model.verified_pose_sigma_factor * placed.sigma, model.verified_pose_sigma_floor);
  placed.outlier_probability = std::max(placed.outlier_probability, model.verified_pose_outlier_probability);
  return placed;
}

PlaceMeasurement GeometryMeasurement(arc_t arc, const ArcPosition& position, ArcImage key,
                                     const PlacementModel& model) {
  // How far the geometry extrapolates from its key-image: along the arc, and in any direction (beside the path too).
  const double along = std::abs(key == ArcImage::kA ? position.along : position.along - 1.0);
  const double distance = key == ArcImage::kA ? position.distance_to_from : position.distance_to_to;
  double right = 1.0 - model.geometry_outlier_probability;
  if (along > 1.0) right *= std::exp(-(along - 1.0) / model.geometry_extrapolation_length);
  if (distance > 1.0 && model.geometry_distance_length > 0.0) {
    right *= std::exp(-(distance - 1.0) / model.geometry_distance_length);
  }
  const double outlier_probability = 1.0 - right;
  // Kept below 1: a measurement that is certainly an outlier carries no information but must not zero the belief.
  return {arc, position.along, model.geometry_sigma, std::min(outlier_probability, 0.999)};
}

PlaceMeasurement KeyImageMeasurement(const MapArc& arc, node_t node, int candidates, const PlacementModel& model,
                                     double beside) {
  const double sigma = std::isfinite(beside) ? std::hypot(model.key_image_sigma, model.key_image_beside_sigma * beside)
                                             : model.key_image_sigma;
  return {arc.id, node == arc.from ? 0.0 : 1.0, sigma, model.key_image_outlier_probability,
          static_cast<double>(std::max(candidates, 1))};
}

}  // namespace retrace
