#include "retrace/repeat/placement.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace retrace {
Vector3d CameraCentre(const Rigid3d& cam_from_world) {
  return -cam_from_world.rotation.transpose() * cam_from_world.translation;
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

double AlongSigma(const Matrix3d& centre_covariance, const Rigid3d& arc_b_from_a) {
  const Vector3d c_b = CameraCentre(arc_b_from_a);
  const double length_sq = c_b.squaredNorm();
  if (!(length_sq > 0)) return std::numeric_limits<double>::infinity();
  const double variance = c_b.dot(centre_covariance * c_b) / (length_sq * length_sq);
  return variance >= 0 ? std::sqrt(variance) : std::numeric_limits<double>::infinity();
}

bool PlacementModel::Check(std::string* error) const {
  const auto fail = [&](const std::string& message) {
    if (error != nullptr) *error = message;
    return false;
  };
  if (!(pose_sigma_floor > 0) || !(geometry_sigma > 0) || !(key_image_sigma > 0)) {
    return fail("placement sigmas must be positive");
  }
  for (const double p : {pose_outlier_probability, geometry_outlier_probability, key_image_outlier_probability}) {
    if (!(p > 0) || !(p < 1)) return fail("placement outlier probabilities must be in (0, 1)");
  }
  return true;
}

PlaceMeasurement PoseMeasurement(arc_t arc, const ArcPosition& position, const AbsolutePose& pose,
                                 const Rigid3d& arc_b_from_a, const PlacementModel& model) {
  double sigma = model.pose_sigma_floor;
  if (pose.covariance_valid) {
    const double fitted = AlongSigma(pose.centre_covariance, arc_b_from_a);
    sigma = std::isfinite(fitted) ? std::hypot(fitted, model.pose_sigma_floor) : 1.0;
  }
  return {arc, position.along, sigma, model.pose_outlier_probability};
}

PlaceMeasurement GeometryMeasurement(arc_t arc, const ArcPosition& position, const PlacementModel& model) {
  return {arc, position.along, model.geometry_sigma, model.geometry_outlier_probability};
}

PlaceMeasurement KeyImageMeasurement(const MapArc& arc, node_t node, int candidates, const PlacementModel& model) {
  return {arc.id, node == arc.from ? 0.0 : 1.0, model.key_image_sigma, model.key_image_outlier_probability,
          static_cast<double>(std::max(candidates, 1))};
}

}  // namespace retrace
