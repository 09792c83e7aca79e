#include "retrace/nav/camera_mount.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

namespace retrace {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

// One constraint on the normal n: a direction in the ground plane (n · v = 0) or the plane's normal (n ∥ v).
struct Constraint {
  Vector3d direction;
  bool is_normal = false;
};

double Residual(const Constraint& constraint, const Vector3d& n) {
  const double cosine = std::min(1.0, std::abs(n.dot(constraint.direction)));
  return constraint.is_normal ? std::acos(cosine) : std::asin(cosine);
}

Vector3d SolveNormal(const std::vector<Constraint>& constraints, const std::vector<bool>& used, double prior_weight) {
  Matrix3d m = prior_weight * Vector3d::UnitX() * Vector3d::UnitX().transpose();
  for (size_t i = 0; i < constraints.size(); ++i) {
    if (!used[i]) continue;
    const Vector3d& v = constraints[i].direction;
    m += constraints[i].is_normal ? Matrix3d(Matrix3d::Identity() - v * v.transpose()) : Matrix3d(v * v.transpose());
  }
  const Eigen::SelfAdjointEigenSolver<Matrix3d> solver(m);
  Vector3d n = solver.eigenvectors().col(0);  // eigenvalues ascending
  if (n.y() < 0) n = -n;
  return n;
}

}  // namespace

double CameraMount::tilt_rad() const { return std::acos(std::clamp(down.normalized().y(), -1.0, 1.0)); }

Matrix3d LevelFromCamera(const Vector3d& down) {
  const Vector3d y = down.normalized();
  Vector3d z = Vector3d::UnitZ() - Vector3d::UnitZ().dot(y) * y;
  // A camera looking straight down or up has no forward direction on the ground: take its -y (up in the image).
  if (z.norm() < 1e-9) z = -Vector3d::UnitY() + Vector3d::UnitY().dot(y) * y;
  z.normalize();
  Matrix3d level;
  level.row(0) = y.cross(z).transpose();
  level.row(1) = y.transpose();
  level.row(2) = z.transpose();
  return level;
}

CameraMount EstimateCameraMount(const Map& map, const CameraMountOptions& options) {
  std::vector<Constraint> constraints;
  for (const MapArc& arc : map.arcs()) {
    const Matrix3d& r = arc.to_from_from.rotation;
    const Vector3d centre = -r.transpose() * arc.to_from_from.translation;  // the second camera in the first's frame
    if (!centre.allFinite() || !r.allFinite() || centre.norm() < 1e-9) continue;
    constraints.push_back({centre.normalized(), false});
    const Eigen::AngleAxisd turn(r);
    if (std::abs(turn.angle()) >= options.min_turn_rad) constraints.push_back({turn.axis().normalized(), true});
  }
  CameraMount estimate;
  if (constraints.empty()) return estimate;

  std::vector<bool> used(constraints.size(), true);
  Vector3d n = SolveNormal(constraints, used, options.no_roll_prior_weight);
  std::vector<double> residuals(constraints.size());
  for (size_t i = 0; i < constraints.size(); ++i) residuals[i] = Residual(constraints[i], n);
  std::vector<double> sorted = residuals;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double limit = std::max(3.0 * sorted[sorted.size() / 2], options.min_outlier_rad);
  for (size_t i = 0; i < constraints.size(); ++i) {
    used[i] = residuals[i] <= limit;
    if (!used[i]) ++estimate.dropped;
  }
  n = SolveNormal(constraints, used, options.no_roll_prior_weight);

  for (size_t i = 0; i < constraints.size(); ++i) {
    if (!used[i]) continue;
    ++(constraints[i].is_normal ? estimate.rotations : estimate.translations);
  }
  estimate.down = n;
  estimate.level_from_camera = LevelFromCamera(n);
  return estimate;
}

}  // namespace retrace
