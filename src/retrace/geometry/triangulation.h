#pragma once

// Triangulation and reprojection on unit bearing vectors, shared by the two-view estimators (5-point and planar) and
// by the point transfer.
//
// Working on bearings (rays) rather than pixels lets one code path serve perspective and omnidirectional cameras:
// "in front of the camera" means a positive distance along the ray, which is also meaningful for rays that point
// sideways or backwards in a panorama.

#include <vector>

#include "retrace/util/types.h"

namespace retrace {

struct TriangulatedPoint {
  // Midpoint of the closest points of the two rays, in camera A's frame.
  Vector3d point_in_a = Vector3d::Zero();
  // Signed distances along the rays of A and B to their closest points (the point is in front of a camera when its
  // distance is positive). For unit bearings these are the distances from the camera centres.
  double depth_a = 0.0;
  double depth_b = 0.0;
};

// Midpoint triangulation (Hartley & Sturm 1997; Lee & Civera 2019 discuss its accuracy) of the rays
// `bearing_a` (frame A) and `bearing_b` (frame B) for the relative pose b_from_a (x_B = R x_A + t). Returns false
// when the rays are (numerically) parallel, i.e. the point is at infinity or there is no baseline.
bool TriangulateMidpoint(const Rigid3d& b_from_a, const Vector3d& bearing_a, const Vector3d& bearing_b,
                         TriangulatedPoint* point);

// True when both rays meet in front of their cameras (cheirality on bearings): the triangulation succeeds and both
// depths are positive.
bool InFrontOfBothCameras(const Rigid3d& b_from_a, const Vector3d& bearing_a, const Vector3d& bearing_b);

// First-order covariance of a point triangulated from two rays (TriangulateMidpoint) when each ray's direction has
// an isotropic angular error of one radian (scale it by σ² in rad²): Σ = Σ_k J_k J_kᵀ over the two tangent directions
// of each ray (J_k by central differences). `point_in_a` is the point in camera A's frame and `centre_b_in_a` camera
// B's centre there; the rays are those from each centre through the point. Its largest axis lies along A's ray and
// grows as (distance from B / sin of the parallax angle): depth is what two views close to each other measure worst.
// Rays closer than `min_sin_parallax` to parallel are taken at that parallax.
Matrix3d TwoViewPointCovariance(const Vector3d& point_in_a, const Vector3d& centre_b_in_a,
                                double min_sin_parallax = 1e-3);

// A point seen along `bearings[i]` from cameras `cam_from_world[i]` (at least two), refined from `initial` by
// Levenberg-Marquardt on the tangent residuals (TangentResidualPx, focal_length_px) of every view, each weighed alike.
// Returns false when it does not converge to a point in front of every camera; `max_residual_px` (optional): the
// largest residual of a view at the result.
bool RefinePointMultiView(const std::vector<Rigid3d>& cam_from_world, const std::vector<Vector3d>& bearings,
                          const Vector3d& initial, double focal_length_px, Vector3d* point,
                          double* max_residual_px = nullptr);

// An orthonormal basis (u, v) of the plane tangent to the unit sphere at `bearing`. For a bearing near the optical
// axis (0, 0, 1), u is close to +x (right) and v close to +y (down), so tangent coordinates times the focal length
// are close to pixel offsets of a perspective image.
void TangentBasis(const Vector3d& bearing, Vector3d* u, Vector3d* v);

// Reprojection residual of the 3D point `point_in_cam` observed along the unit `bearing`, in pixels: the component
// of the unit direction towards the point that is orthogonal to the bearing (≈ the angle between them, in radians),
// expressed in the tangent basis of the bearing and multiplied by `focal_length_px`. A point behind the bearing
// (angle > 90°) gets a residual of at least `focal_length_px` in magnitude, so it never looks like a good fit.
Vector2d TangentResidualPx(const Vector3d& bearing, const Vector3d& point_in_cam, double focal_length_px);
// The same with the bearing's tangent basis (u, v) = TangentBasis(bearing) given: for the many residuals of one
// bearing that a robust estimator computes (two_view_geometry.cc). The same result, bit for bit.
Vector2d TangentResidualPx(const Vector3d& bearing, const Vector3d& u, const Vector3d& v, const Vector3d& point_in_cam,
                           double focal_length_px);

}  // namespace retrace
