#include "retrace/repeat/taught_path.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <vector>

#include <Eigen/Geometry>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "retrace/util/robust_random_walk.h"
#include "retrace/util/statistics.h"

namespace retrace {
namespace {

// The signed angle from u to v (radians, positive counter-clockwise: to the left in (right, forward) coordinates).
double SignedAngle(const Vector2d& u, const Vector2d& v) {
  return std::atan2(u.x() * v.y() - u.y() * v.x(), u.dot(v));
}

// A cubic Hermite segment on the ground plane, coordinates (right, forward) of the current arc's key-image a.
struct Segment {
  arc_t arc = kInvalidArcId;
  Vector2d p0, p1, t0, t1;  // end points and tangents (scaled by the chord's length)

  Vector2d At(double u) const {
    const double u2 = u * u, u3 = u2 * u;
    return (2 * u3 - 3 * u2 + 1) * p0 + (u3 - 2 * u2 + u) * t0 + (-2 * u3 + 3 * u2) * p1 + (u3 - u2) * t1;
  }
  Vector2d Derivative(double u) const {
    const double u2 = u * u;
    return (6 * u2 - 6 * u) * p0 + (3 * u2 - 4 * u + 1) * t0 + (-6 * u2 + 6 * u) * p1 + (3 * u2 - 2 * u) * t1;
  }
  Vector2d SecondDerivative(double u) const {
    return (12 * u - 6) * p0 + (6 * u - 4) * t0 + (-12 * u + 6) * p1 + (6 * u - 2) * t1;
  }
  // Signed curvature, positive turning left (counter-clockwise in (right, forward) coordinates).
  double Curvature(double u) const {
    const Vector2d d = Derivative(u), dd = SecondDerivative(u);
    const double speed = d.norm();
    return speed > 1e-12 ? (d.x() * dd.y() - d.y() * dd.x()) / (speed * speed * speed) : 0.0;
  }
  // Length from u0 to u1 (Simpson's rule).
  double Length(double u0 = 0.0, double u1 = 1.0) const {
    constexpr int kSteps = 16;
    const double h = (u1 - u0) / kSteps;
    double sum = 0.0;
    for (int i = 0; i <= kSteps; ++i) {
      const double w = (i == 0 || i == kSteps) ? 1 : (i % 2 == 1 ? 4 : 2);
      sum += w * Derivative(u0 + i * h).norm();
    }
    return sum * h / 3;
  }
  // The parameter of the nearest point to `c` (a coarse scan, then a ternary search around the best sample).
  double Nearest(const Vector2d& c) const {
    constexpr int kSamples = 32;
    int best = 0;
    double best_distance = std::numeric_limits<double>::infinity();
    for (int i = 0; i <= kSamples; ++i) {
      const double d = (At(double(i) / kSamples) - c).squaredNorm();
      if (d < best_distance) {
        best_distance = d;
        best = i;
      }
    }
    double lo = std::max(0, best - 1) / double(kSamples), hi = std::min(kSamples, best + 1) / double(kSamples);
    for (int i = 0; i < 40; ++i) {
      const double m1 = lo + (hi - lo) / 3, m2 = hi - (hi - lo) / 3;
      if ((At(m1) - c).squaredNorm() < (At(m2) - c).squaredNorm()) {
        hi = m2;
      } else {
        lo = m1;
      }
    }
    return 0.5 * (lo + hi);
  }
};

}  // namespace

struct TaughtPath::ArcGround {
  GroundPlane plane;
  double metres_per_unit = 0.0;  // h / d_b of this arc alone; 0 when its plane is invalid
  // The median over the window (computed on first use) and its relative spread.
  bool window_done = false;
  std::optional<double> window_scale;
  double window_sigma = 0.0;
};

bool TaughtPathOptions::Check(std::string* error) const {
  const auto fail = [error](const std::string& message) {
    if (error != nullptr) *error = message;
    return false;
  };
  if (!(camera_height >= 0 && camera_height <= 100)) {
    return fail(fmt::format("camera_height must be in [0, 100] m, got {}", camera_height));
  }
  if (!(tangent_sigma_rad >= 0 && tangent_sigma_rad < 1)) {
    return fail(fmt::format("tangent_sigma_rad must be in [0, 1), got {}", tangent_sigma_rad));
  }
  if (travel_window < 0 || travel_window > 1000) {
    return fail(fmt::format("travel_window must be in 0..1000, got {}", travel_window));
  }
  if (!(travel_sigma_rad >= 0 && travel_sigma_rad < 1)) {
    return fail(fmt::format("travel_sigma_rad must be in [0, 1), got {}", travel_sigma_rad));
  }
  if (!(travel_min_turn_rad > 0 && travel_min_turn_rad < 1)) {
    return fail(fmt::format("travel_min_turn_rad must be in (0, 1), got {}", travel_min_turn_rad));
  }
  if (normal_arcs < 1 || normal_arcs > 1000) return fail(fmt::format("normal_arcs must be in 1..1000, got {}", normal_arcs));
  if (scale_window < 0 || scale_window > 100) {
    return fail(fmt::format("scale_window must be in 0..100, got {}", scale_window));
  }
  if (!(relative_scale_sigma > 0 && relative_scale_sigma < 1)) {
    return fail(fmt::format("relative_scale_sigma must be in (0, 1), got {}", relative_scale_sigma));
  }
  if (!(ground_scale_sigma > 0 && ground_scale_sigma < 1)) {
    return fail(fmt::format("ground_scale_sigma must be in (0, 1), got {}", ground_scale_sigma));
  }
  if (!(ground_outlier_probability >= 0 && ground_outlier_probability < 1)) {
    return fail(fmt::format("ground_outlier_probability must be in [0, 1), got {}", ground_outlier_probability));
  }
  return ground.Check(error);
}

CombinedScale CombineArcScales(const std::vector<CarriedScale>& scales, const TaughtPathOptions& options) {
  const double sigma_r2 = options.relative_scale_sigma * options.relative_scale_sigma;
  std::vector<CarriedObservation> observations;
  for (const CarriedScale& s : scales) {
    observations.push_back({s.log_metres_per_unit, std::max(options.ground_scale_sigma, s.fit_sigma),
                            sigma_r2 * s.steps, s.side});
  }
  const CombinedObservation log_scale =
      CombineCarriedObservations(observations, options.ground_outlier_probability,
                                 std::log(options.ground.max_distance / options.ground.min_distance));
  CombinedScale combined;
  combined.valid = log_scale.valid;
  combined.metres_per_unit = std::exp(log_scale.value);
  combined.sigma = log_scale.sigma;
  combined.inliers = log_scale.inliers;
  return combined;
}

TaughtPath::TaughtPath(const Map& map, const CameraModel& camera, const TaughtPathOptions& options)
    : map_(map), camera_(camera.Clone()), options_(options) {
  std::string error;
  if (!options_.Check(&error)) throw std::invalid_argument("TaughtPathOptions: " + error);
}

TaughtPath::~TaughtPath() = default;

const MapArc* TaughtPath::Next(const MapArc& arc) const {
  const auto arcs = map_.ArcsFrom(arc.to);
  return arcs.empty() ? nullptr : arcs.front();
}

const MapArc* TaughtPath::Previous(const MapArc& arc) const {
  const auto arcs = map_.ArcsTo(arc.from);
  return arcs.empty() ? nullptr : arcs.front();
}

const std::optional<Vector3d>& TaughtPath::GroundNormal() {
  if (normal_estimated_ || !enabled()) return normal_;
  normal_estimated_ = true;
  if (options_.ground.normal_in_camera) {
    normal_ = options_.ground.normal_in_camera->normalized();
    return normal_;
  }
  // Free planes (three unknowns each) of arcs spread evenly over the map.
  const auto& arcs = map_.arcs();
  const int count = std::min<int>(options_.normal_arcs, static_cast<int>(arcs.size()));
  std::vector<GroundPlane> planes;
  for (int i = 0; i < count; ++i) {
    const MapArc& arc = arcs[static_cast<size_t>((i + 0.5) * arcs.size() / count)];
    const MapNode* a = map_.FindNode(arc.from);
    const MapNode* b = map_.FindNode(arc.to);
    if (a == nullptr || b == nullptr) continue;
    planes.push_back(EstimateGroundPlane(map_.KeyImage(a->id), map_.KeyImage(b->id), *camera_, arc.to_from_from,
                                         options_.ground));
  }
  normal_ = CommonGroundNormal(planes, std::min(3, count));
  return normal_;
}

const TaughtPath::ArcGround& TaughtPath::Ground(arc_t arc_id) {
  auto it = grounds_.find(arc_id);
  if (it != grounds_.end()) return *it->second;
  auto ground = std::make_unique<ArcGround>();
  const MapArc* arc = map_.FindArc(arc_id);
  if (arc != nullptr && arc->ground_fit && GroundNormal()) {
    // Fitted at teach for this normal (LoadMapForLocalizer attaches the fits only with the normal they were made for).
    ground->plane.valid = arc->ground_fit->distance_b > 0;
    ground->plane.distance_b = arc->ground_fit->distance_b;
    ground->plane.distance_sigma = arc->ground_fit->distance_sigma;
    if (ground->plane.valid) ground->metres_per_unit = options_.camera_height / ground->plane.distance_b;
  } else if (arc != nullptr && GroundNormal()) {
    GroundPlaneOptions options = options_.ground;
    options.normal_in_camera = *normal_;
    const MapNode* a = map_.FindNode(arc->from);
    const MapNode* b = map_.FindNode(arc->to);
    if (a != nullptr && b != nullptr) {
      ground->plane = EstimateGroundPlane(map_.KeyImage(a->id), map_.KeyImage(b->id), *camera_, arc->to_from_from,
                                         options);
      if (ground->plane.valid) ground->metres_per_unit = options_.camera_height / ground->plane.distance_b;
      spdlog::debug("taught path: arc {} ground plane {}: d_b {:.4f} +- {:.4f} units, rms {:.1f}, overlap {:.2f}, "
                    "{:.4f} m/unit",
                    arc_id, ground->plane.valid ? "valid" : "invalid", ground->plane.distance_b,
                    ground->plane.distance_sigma, ground->plane.rms_residual, ground->plane.overlap,
                    ground->metres_per_unit);
    }
  }
  return *grounds_.emplace(arc_id, std::move(ground)).first->second;
}

MapArc::GroundFit TaughtPath::GroundFit(arc_t arc_id) {
  MapArc::GroundFit fit;
  if (!enabled()) return fit;
  const GroundPlane& plane = Ground(arc_id).plane;
  if (plane.valid) fit = {plane.distance_b, plane.distance_sigma};
  return fit;
}

template <typename Visit>
void TaughtPath::ForEachNeighbour(const MapArc& arc, int window, Visit&& visit) const {
  for (const int direction : {+1, -1}) {
    const MapArc* current = &arc;
    double log_unit_ratio = 0.0;  // a length in units of `arc` times exp(this) = the same length in units of `current`
    for (int step = 0; step < window; ++step) {
      const MapArc* neighbour = direction > 0 ? Next(*current) : Previous(*current);
      if (neighbour == nullptr) break;
      const std::optional<double> scale = direction > 0 ? map_.ScaleAt(current->to, current->id, neighbour->id)
                                                        : map_.ScaleAt(current->from, neighbour->id, current->id);
      if (!scale || !(*scale > 0)) break;
      log_unit_ratio += direction > 0 ? -std::log(*scale) : std::log(*scale);
      visit(*neighbour, log_unit_ratio, direction, step + 1);
      current = neighbour;
    }
  }
}

std::optional<double> TaughtPath::MetresPerUnit(arc_t arc_id) {
  if (!enabled()) return std::nullopt;
  Ground(arc_id);
  ArcGround& ground = *grounds_.at(arc_id);
  if (ground.window_done) return ground.window_scale;
  ground.window_done = true;
  const MapArc* arc = map_.FindArc(arc_id);
  if (arc == nullptr) return std::nullopt;
  // This arc's own scale and its neighbours' carried into its unit through the relative scales stored at the
  // nodes (design §1: a length in units of the arc leaving a node times the scale is that length in units of the
  // arc entering it).
  const auto fit_sigma = [](const GroundPlane& plane) {
    return plane.distance_b > 0 ? plane.distance_sigma / plane.distance_b : 0.0;
  };
  std::vector<CarriedScale> scales;
  if (ground.metres_per_unit > 0) {
    scales.push_back({std::log(ground.metres_per_unit), 0, 0, fit_sigma(ground.plane)});
  }
  ForEachNeighbour(*arc, options_.scale_window,
                   [&](const MapArc& neighbour, double log_unit_ratio, int side, int steps) {
                     const ArcGround& neighbour_ground = Ground(neighbour.id);
                     if (neighbour_ground.metres_per_unit > 0) {
                       scales.push_back({std::log(neighbour_ground.metres_per_unit) + log_unit_ratio, side, steps,
                                         fit_sigma(neighbour_ground.plane)});
                     }
                   });
  const CombinedScale combined = CombineArcScales(scales, options_);
  if (!combined.valid) return std::nullopt;
  spdlog::debug("taught path: arc {} scale {:.4f} m/unit +- {:.1f} % from {} of {} ground planes", arc_id,
                combined.metres_per_unit, 100 * combined.sigma, combined.inliers, scales.size());
  ground.window_scale = combined.metres_per_unit;
  ground.window_sigma = combined.sigma;
  return ground.window_scale;
}

std::vector<Vector2d> KeyImageTangents(const std::vector<Vector2d>& centres, const std::vector<Vector2d>& headings) {
  std::vector<Vector2d> tangents(centres.size(), Vector2d::Zero());
  for (size_t i = 0; i + 1 < centres.size() && i + 1 < headings.size(); ++i) {
    const Vector2d chord = centres[i + 1] - centres[i];
    if (!(chord.norm() > 1e-12)) continue;
    const double turn = SignedAngle(headings[i], headings[i + 1]);
    tangents[i] += Eigen::Rotation2Dd(-turn / 2) * chord.normalized();
    tangents[i + 1] += Eigen::Rotation2Dd(turn / 2) * chord.normalized();
  }
  for (Vector2d& t : tangents) {
    if (t.norm() > 1e-12) t.normalize();
  }
  return tangents;
}

TravelModel FitTravelModel(const std::vector<ArcTravel>& arcs, double min_turn) {
  TravelModel model;
  if (arcs.empty()) return model;
  // β = atan(camera_ahead · κ) - mount_yaw; on a straight arc -mount_yaw.
  std::vector<double> straight;
  for (const ArcTravel& arc : arcs) {
    if (std::abs(arc.turn) < min_turn) straight.push_back(-arc.chord_angle);
  }
  model.straight_arcs = static_cast<int>(straight.size());
  model.turning_arcs = static_cast<int>(arcs.size() - straight.size());
  if (straight.empty()) {
    for (const ArcTravel& arc : arcs) straight.push_back(-arc.chord_angle);
  }
  std::vector<double> votes = std::move(straight);  // mount_yaw's, from the last fit below
  model.mount_yaw = Median(votes);
  for (int iteration = 0; iteration < 3 && model.turning_arcs > 0; ++iteration) {
    std::vector<double> ahead;
    for (const ArcTravel& arc : arcs) {
      if (std::abs(arc.turn) >= min_turn && arc.length > 0) {
        ahead.push_back(std::tan(arc.chord_angle + model.mount_yaw) * arc.length / arc.turn);
      }
    }
    if (ahead.empty()) break;
    model.camera_ahead = Median(std::move(ahead));
    std::vector<double> yaw;
    for (const ArcTravel& arc : arcs) {
      if (arc.length > 0) yaw.push_back(std::atan(model.camera_ahead * arc.turn / arc.length) - arc.chord_angle);
    }
    votes = std::move(yaw);
    model.mount_yaw = Median(votes);
  }
  // The median's standard error from the votes' robust spread, and the straight arcs' curvatures' spread.
  const auto enough = [](const std::vector<double>& v) {
    return static_cast<int>(v.size()) >= TravelModel::kMinVotesForSigma;
  };
  if (enough(votes)) {
    model.mount_yaw_sigma = std::sqrt(M_PI / 2) * RobustSigmaAbout(votes, model.mount_yaw) /
                            std::sqrt(static_cast<double>(votes.size()));
  }
  std::vector<double> curvatures;
  for (const ArcTravel& arc : arcs) {
    if (std::abs(arc.turn) < min_turn && arc.length > 0) curvatures.push_back(arc.turn / arc.length);
  }
  if (enough(curvatures)) model.curvature_sigma = RobustSigmaAbout(curvatures, Median(curvatures));
  model.valid = true;
  return model;
}

ArcTravel TaughtPath::MeasureTravel(const MapArc& arc, double unit_length) const {
  // On the ground plane of key-image a (coordinates right, forward; the normal is the same in every key-image's frame,
  // the camera being fixed on the vehicle).
  const Vector3d& n = *normal_;
  const Vector3d forward = (Vector3d::UnitZ() - n.z() * n).normalized();
  const Vector3d right = n.cross(forward);
  const auto flat = [&](const Vector3d& x) { return Vector2d(right.dot(x), forward.dot(x)); };
  const Vector3d centre_b = -(arc.to_from_from.rotation.transpose() * arc.to_from_from.translation);
  const Vector2d axis_a(0, 1);
  ArcTravel travel;
  travel.turn = SignedAngle(axis_a, flat(arc.to_from_from.rotation.transpose() * Vector3d::UnitZ()));
  travel.chord_angle = SignedAngle(axis_a, flat(centre_b)) - travel.turn / 2;
  travel.length = unit_length * flat(centre_b).norm();
  return travel;
}

const TravelModel& TaughtPath::Travel(const MapArc& arc) {
  const auto it = travel_.find(arc.id);
  if (it != travel_.end()) return it->second;
  std::vector<ArcTravel> arcs{MeasureTravel(arc, 1.0)};
  ForEachNeighbour(arc, options_.travel_window, [&](const MapArc& neighbour, double log_unit_ratio, int, int) {
    arcs.push_back(MeasureTravel(neighbour, std::exp(-log_unit_ratio)));
  });
  const TravelModel model = FitTravelModel(arcs, options_.travel_min_turn_rad);
  spdlog::debug("taught path: arc {} travel model from {} arcs ({} turning): mount yaw {:.3f} +- {:.3f} deg, camera "
                "ahead {:.3f} units",
                arc.id, arcs.size(), model.turning_arcs, model.mount_yaw * 180 / M_PI,
                model.mount_yaw_sigma * 180 / M_PI, model.camera_ahead);
  return travel_.emplace(arc.id, model).first->second;
}

TravelModel TaughtPath::MapTravelModel() {
  if (!enabled() || !GroundNormal()) return {};
  std::vector<ArcTravel> arcs;
  for (const MapArc& arc : map_.arcs()) {
    if (const std::optional<double> metres_per_unit = MetresPerUnit(arc.id)) {
      arcs.push_back(MeasureTravel(arc, *metres_per_unit));
    }
  }
  return FitTravelModel(arcs, options_.travel_min_turn_rad);
}

PathPose TaughtPath::Locate(arc_t pose_arc, const Rigid3d& current_from_a, const PoseCovariance* covariance,
                            arc_t reported_arc) {
  PathPose pose;
  const MapArc* arc = map_.FindArc(pose_arc);
  if (!enabled() || arc == nullptr || !GroundNormal()) return pose;
  const std::optional<double> scale = MetresPerUnit(pose_arc);
  if (!scale) return pose;
  const double arc_sigma = grounds_.at(pose_arc)->window_sigma;

  // Key-image centres in the frame of the arc's key-image a, in metres: [previous arc's a], a, b, [next arc's b].
  const Vector3d centre_b = -(arc->to_from_from.rotation.transpose() * arc->to_from_from.translation) * *scale;
  std::vector<Vector3d> centres;
  std::vector<Vector3d> axes;  // the key-images' optical axes, same frame
  std::vector<arc_t> segment_arcs;
  const MapArc* previous = Previous(*arc);
  const MapArc* next = Next(*arc);
  if (previous != nullptr) {
    if (const auto previous_scale = MetresPerUnit(previous->id)) {
      // Key-image a of the previous arc is the origin of its frame: at t (its unit) in the frame of its b = our a.
      centres.push_back(previous->to_from_from.translation * *previous_scale);
      axes.push_back(previous->to_from_from.rotation * Vector3d::UnitZ());
      segment_arcs.push_back(previous->id);
    }
  }
  centres.push_back(Vector3d::Zero());
  axes.push_back(Vector3d::UnitZ());
  segment_arcs.push_back(arc->id);
  centres.push_back(centre_b);
  axes.push_back(arc->to_from_from.rotation.transpose() * Vector3d::UnitZ());
  if (next != nullptr) {
    if (const auto next_scale = MetresPerUnit(next->id)) {
      const Vector3d next_b_in_b =
          -(next->to_from_from.rotation.transpose() * next->to_from_from.translation) * *next_scale;
      centres.push_back(arc->to_from_from.rotation.transpose() * next_b_in_b + centre_b);
      axes.push_back(arc->to_from_from.rotation.transpose() *
                     (next->to_from_from.rotation.transpose() * Vector3d::UnitZ()));
      segment_arcs.push_back(next->id);
    }
  }
  const size_t index_a = previous != nullptr && segment_arcs.front() == previous->id ? 1 : 0;

  // The ground plane's frame: normal n (down), forward along the arc's chord, right = n × forward.
  const Vector3d& n = *normal_;
  const Vector3d chord = centre_b - n.dot(centre_b) * n;
  if (!(chord.norm() > 1e-9)) return pose;
  const Vector3d forward = chord.normalized();
  const Vector3d right = n.cross(forward);
  const auto flat = [&](const Vector3d& x) { return Vector2d(right.dot(x), forward.dot(x)); };

  std::vector<Vector2d> points;
  for (const Vector3d& c : centres) points.push_back(flat(c));
  std::vector<Vector2d> headings;
  for (const Vector3d& axis : axes) headings.push_back(flat(axis));
  const std::vector<Vector2d> node_tangents = KeyImageTangents(points, headings);
  // The direction the taught camera travelled at each key-image, the heading error's reference where the arcs on
  // either side of it are straight (turn less than travel_min_turn_rad; travel_weight 1): its optical axis turned by
  // the travel model's β at the curvature there (the turns of the arcs on either side over their lengths,
  // interpolated between the arcs' middles). In turns the curve's tangents are the reference (weight 0): there the
  // curvature changes within an arc, which the Hermite curve through the key-images' centres follows and the model's
  // curvatures at the key-images do not (docs/path-tracking.md, "The direction of travel from the vehicle's
  // kinematics").
  std::vector<Vector2d> travel = node_tangents;
  std::vector<double> travel_weight(points.size(), 0.0);
  double travel_sigma = options_.travel_sigma_rad;
  if (options_.travel_window > 0) {
    const TravelModel& model = Travel(*arc);
    if (std::isfinite(model.mount_yaw_sigma)) travel_sigma = model.DirectionSigma();
    std::vector<double> arc_turn, arc_length, arc_curvature;
    for (size_t i = 0; i + 1 < points.size(); ++i) {
      arc_turn.push_back(SignedAngle(headings[i], headings[i + 1]));
      arc_length.push_back((points[i + 1] - points[i]).norm());
      arc_curvature.push_back(arc_length.back() > 1e-9 ? arc_turn.back() / arc_length.back() : 0.0);
    }
    const auto straight_arc = [&](size_t j) { return std::abs(arc_turn[j]) < options_.travel_min_turn_rad; };
    for (size_t i = 0; i < points.size(); ++i) {
      double curvature = 0.0;
      if (i > 0 && i < arc_length.size()) {
        const double length_in = arc_length[i - 1], length_out = arc_length[i];
        curvature = (arc_curvature[i - 1] * length_out + arc_curvature[i] * length_in) /
                    std::max(1e-9, length_in + length_out);
      } else if (i > 0) {
        curvature = arc_curvature[i - 1];
      } else if (!arc_curvature.empty()) {
        curvature = arc_curvature[0];
      }
      const bool straight = (i == 0 || straight_arc(i - 1)) && (i >= arc_turn.size() || straight_arc(i));
      // The model's camera_ahead is in the current arc's unit, the curvature in 1/m: κ · (metres per unit) per unit.
      if (straight && headings[i].norm() > 1e-9) {
        travel_weight[i] = 1.0;
        travel[i] = Eigen::Rotation2Dd(model.TravelAngle(curvature * *scale)) * headings[i].normalized();
      }
    }
  }
  std::vector<Segment> segments;
  for (size_t i = 0; i + 1 < points.size(); ++i) {
    Segment s;
    s.arc = segment_arcs[i];
    s.p0 = points[i];
    s.p1 = points[i + 1];
    const double length = (s.p1 - s.p0).norm();
    s.t0 = node_tangents[i] * length;
    s.t1 = node_tangents[i + 1] * length;
    segments.push_back(s);
  }

  // The camera's centre and optical axis in the arc's frame and metres.
  const Vector3d centre = -(current_from_a.rotation.transpose() * current_from_a.translation) * *scale;
  const Vector3d axis = current_from_a.rotation.transpose() * Vector3d::UnitZ();
  const Vector2d c = flat(centre);
  size_t best_segment = 0;
  double best_u = 0.0, best_distance = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < segments.size(); ++i) {
    const double u = segments[i].Nearest(c);
    const double d = (segments[i].At(u) - c).norm();
    if (d < best_distance) {
      best_distance = d;
      best_segment = i;
      best_u = u;
    }
  }
  const Segment& segment = segments[best_segment];
  const Vector2d tangent = segment.Derivative(best_u).normalized();
  const Vector2d right_of_path(tangent.y(), -tangent.x());
  pose.lateral_m = (c - segment.At(best_u)).dot(right_of_path);
  const Vector2d look = flat(axis);
  if (!(look.norm() > 1e-9)) return pose;
  // The heading's reference: the direction of travel turning from one key-image's to the next's along the segment,
  // blended with the curve's tangent by the key-images' weights (one where both are on a straight).
  const Vector2d& travel_0 = travel[best_segment];
  const Vector2d& travel_1 = travel[best_segment + 1];
  const Vector2d travelled = Eigen::Rotation2Dd(best_u * SignedAngle(travel_0, travel_1)) * travel_0.normalized();
  const double weight = (1 - best_u) * travel_weight[best_segment] + best_u * travel_weight[best_segment + 1];
  const Vector2d reference = Eigen::Rotation2Dd(weight * SignedAngle(tangent, travelled)) * tangent;
  pose.heading_error_rad = std::atan2(reference.y() * look.x() - reference.x() * look.y(), reference.dot(look));
  pose.curvature = segment.Curvature(best_u);

  // Distance along the path from the reported arc's key-image a.
  double along = segment.Length(0.0, best_u);
  for (size_t i = index_a; i < best_segment; ++i) along += segments[i].Length();
  for (size_t i = best_segment; i < index_a; ++i) along -= segments[i].Length();
  size_t reported = index_a;
  for (size_t i = 0; i < segments.size(); ++i) {
    if (segments[i].arc == reported_arc) reported = i;
  }
  for (size_t i = index_a; i < reported; ++i) along -= segments[i].Length();
  for (size_t i = reported; i < index_a; ++i) along += segments[i].Length();
  pose.along_m = along;
  pose.arc_length_m = segments[reported].Length();
  pose.to_next_m = pose.arc_length_m - along;

  // The sharpest curvature from here to the end of the path known ahead.
  double ahead = pose.curvature;
  for (size_t i = best_segment; i < segments.size(); ++i) {
    for (int k = 0; k <= 8; ++k) {
      const double u = i == best_segment ? best_u + (1 - best_u) * k / 8.0 : k / 8.0;
      const double kappa = segments[i].Curvature(u);
      if (std::abs(kappa) > std::abs(ahead)) ahead = kappa;
    }
  }
  pose.curvature_ahead = ahead;

  // First-order uncertainty of the lateral offset: the centre's covariance across the path, and the scale's.
  const Vector3d across = right_of_path.x() * right + right_of_path.y() * forward;
  const double pose_lateral_variance =
      covariance != nullptr ? *scale * *scale * across.dot(covariance->centre * across) : 0.0;
  pose.lateral_sigma_m = std::sqrt(std::pow(pose.lateral_m * arc_sigma, 2) + pose_lateral_variance);
  // ... along the path likewise; the heading turns about the ground's normal, which a small rotation δω of the camera
  // (its own frame) turns by the normal's component of δω there (first order, exact for a level optical axis).
  const Vector3d along_path = tangent.x() * right + tangent.y() * forward;
  double along_variance = std::pow(pose.along_m * arc_sigma, 2);
  if (covariance != nullptr) along_variance += *scale * *scale * along_path.dot(covariance->centre * along_path);
  pose.along_sigma_m = std::sqrt(along_variance);
  // The reference's own variance: the chords' where the curve's tangent is taken, the travel model's on straights.
  double heading_variance = (1 - weight) * options_.tangent_sigma_rad * options_.tangent_sigma_rad +
                            weight * travel_sigma * travel_sigma;
  if (covariance != nullptr) {
    const Vector3d normal_in_camera = current_from_a.rotation * n;
    heading_variance += std::max(0.0, normal_in_camera.dot(covariance->rotation * normal_in_camera));
  }
  pose.heading_sigma_rad = std::sqrt(heading_variance);
  // The heading's regression on the offset. A small rotation δω turns the optical axis by Rᵀ (z × δω) (the camera
  // becoming exp(δω) · current_from_a), which turns its trace on the ground by δψ = gᵀ δω, g = (R g_axis) × z with
  // g_axis the heading's gradient in the axis; the offset moves by δe = s acrossᵀ δC (s metres per unit).
  if (pose_lateral_variance > 0) {
    const double x = reference.dot(look);
    const double y = reference.y() * look.x() - reference.x() * look.y();  // ψ = atan2(y, x)
    const Vector2d gradient_look = (x * Vector2d(reference.y(), -reference.x()) - y * reference) / (x * x + y * y);
    const Vector3d gradient_axis = gradient_look.x() * right + gradient_look.y() * forward;
    const Vector3d g = (current_from_a.rotation * gradient_axis).cross(Vector3d::UnitZ());
    pose.heading_per_lateral = *scale * g.dot(covariance->rotation_centre * across) / pose_lateral_variance;
  }
  pose.frame_lateral_m = pose.lateral_m;
  pose.frame_lateral_sigma_m = pose.lateral_sigma_m;
  pose.scale_sigma = arc_sigma;
  pose.valid = std::isfinite(pose.lateral_m) && std::isfinite(pose.heading_error_rad) && std::isfinite(pose.along_m);
  return pose;
}

}  // namespace retrace
