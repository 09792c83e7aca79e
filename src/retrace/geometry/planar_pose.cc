#include "retrace/geometry/planar_pose.h"

#include <cmath>

#include <Eigen/SVD>

#include "retrace/geometry/triangulation.h"

namespace retrace {

Rigid3d PlanarPose(double theta, double beta) {
  Matrix3d r;
  const double c = std::cos(theta), s = std::sin(theta);
  r << c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c;
  return Rigid3d(r, Vector3d(std::sin(beta), 0.0, std::cos(beta)));
}

double PlanarHeading(const Rigid3d& b_from_a) {
  const Vector3d centre_b_in_a = -b_from_a.rotation.transpose() * b_from_a.translation;
  return std::atan2(centre_b_in_a.x(), centre_b_in_a.z());
}

bool SolvePlanarLinear(const std::vector<Vector3d>& bearings_a, const std::vector<Vector3d>& bearings_b,
                       const std::vector<int>& indices, std::vector<Rigid3d>* poses) {
  if (indices.size() < 3) return false;
  // Booij 2007, eq. (B.2) in retrace's axes: f_Bᵀ E f_A = fb0 fa1 e01 + fb1 fa0 e10 + fb1 fa2 e12 + fb2 fa1 e21.
  Eigen::Matrix4d ata = Eigen::Matrix4d::Zero();
  for (int i : indices) {
    const Vector3d& fa = bearings_a[i];
    const Vector3d& fb = bearings_b[i];
    const Vector4d row(fb.x() * fa.y(), fb.y() * fa.x(), fb.y() * fa.z(), fb.z() * fa.y());
    ata += row * row.transpose();
  }
  if (!ata.allFinite()) return false;
  const Eigen::JacobiSVD<Eigen::Matrix4d> svd(ata, Eigen::ComputeFullV);
  const Vector4d sv = svd.singularValues();
  // A 1-D null space is required (the second smallest singular value must be clearly non-zero).
  if (!(sv(2) > 1e-12 * sv(0))) return false;
  const Vector4d e = svd.matrixV().col(3);
  const double e01 = e(0), e10 = e(1), e12 = e(2), e21 = e(3);
  if (std::hypot(e01, e21) < 1e-9 || std::hypot(e10, e12) < 1e-9) return false;
  // e01 = -cos β, e21 = sin β; e10 = cos(θ-β), e12 = sin(θ-β) (up to a common scale and sign).
  const double beta = std::atan2(e21, -e01);
  const double theta = std::atan2(e12, e10) + beta;
  // -E gives β + π and the same θ: the two signs of t.
  for (const double b : {beta, beta + M_PI}) {
    const Rigid3d pose = PlanarPose(theta, b);
    bool all_in_front = true;
    for (int i : indices) {
      if (!InFrontOfBothCameras(pose, bearings_a[i], bearings_b[i])) {
        all_in_front = false;
        break;
      }
    }
    if (all_in_front) poses->push_back(pose);
  }
  return true;
}

namespace {

// θ ← θ + δ₀ (R ← R_y(δ₀) R) and t ← R_y(δ₁) t: both stay planar.
Rigid3d UpdatePlanarPose(const Rigid3d& pose, const double* delta) {
  const Matrix3d ry0 = PlanarPose(delta[0], 0.0).rotation;
  const Matrix3d ry1 = PlanarPose(delta[1], 0.0).rotation;
  return Rigid3d(ry0 * pose.rotation, ry1 * pose.translation);
}

}  // namespace

internal::PoseManifold internal::PlanarPoseManifold() { return internal::PoseManifold{2, &UpdatePlanarPose}; }

TwoViewGeometry EstimatePlanarRelativePose(const std::vector<Vector3d>& bearings_a,
                                           const std::vector<Vector3d>& bearings_b, double focal_length_px,
                                           const TwoViewOptions& options) {
  return internal::EstimateTwoView(
      bearings_a, bearings_b, focal_length_px, options, 3,
      [&](const std::vector<int>& sample, std::vector<Rigid3d>* poses) {
        SolvePlanarLinear(bearings_a, bearings_b, sample, poses);
      },
      internal::PoseManifold{2, &UpdatePlanarPose});
}

}  // namespace retrace
