#pragma once

// Relative pose under planar motion (Booij et al. 2007, §B.3; design §3.2).
//
// A robot on a flat floor whose camera axes are aligned with the vehicle rotates only about the vertical axis and
// translates horizontally. In retrace's camera frame (x right, y down, z forward) the vertical axis is y, so
//
//     R = R_y(θ) = [[cos θ, 0, sin θ], [0, 1, 0], [-sin θ, 0, cos θ]],    t = (sin β, 0, cos β),
//
// and E = [t]ₓ R has only four non-zero entries:
//
//     E = [[0, e01, 0], [e10, 0, e12], [0, e21, 0]]
//       = [[0, -cos β, 0], [cos(θ-β), 0, sin(θ-β)], [0, sin β, 0]].
//
// Each correspondence gives one linear equation f_Bᵀ E f_A = 0 in (e01, e10, e12, e21); three correspondences fix the
// 1-D null space (Booij's note: 3 is the true minimum of the linear method; the paper sampled 4). θ and β are read
// from the two halves of the null vector, so the recovered E always satisfies the planar constraints and the
// rotation is unique; only the sign of t is ambiguous, and the cheirality test on the sample resolves it.
//
// The robust loop (two_view_geometry.h) rejects hypotheses whose sample is not in front of both cameras, and inliers
// are correspondences with a low Sampson error AND in front of both cameras (Booij 2007, §B.3). The refinement keeps
// the motion planar (parameters θ and β).

#include <vector>

#include "retrace/geometry/two_view_geometry.h"

namespace retrace {

// Robust planar relative pose b_from_a from bearings; same options and result as EstimateRelativePose(). The rotation
// of the result is exactly about the camera's y axis and its translation has a zero y component.
TwoViewGeometry EstimatePlanarRelativePose(const std::vector<Vector3d>& bearings_a,
                                           const std::vector<Vector3d>& bearings_b, double focal_length_px,
                                           const TwoViewOptions& options = TwoViewOptions());

// Linear planar solver on the correspondences `indices` (3 or more; least squares beyond 3): appends the candidate
// poses that put all of them in front of both cameras. Returns false when the system is degenerate.
bool SolvePlanarLinear(const std::vector<Vector3d>& bearings_a, const std::vector<Vector3d>& bearings_b,
                       const std::vector<int>& indices, std::vector<Rigid3d>* poses);

// Planar pose from the rotation angle θ about y and the translation direction angle β (see above).
Rigid3d PlanarPose(double theta, double beta);

// Heading towards camera B as seen from camera A (Booij 2007, eq. B.4, φ = atan2(t_y, t_x) in the paper's axes,
// where the horizontal plane is spanned by its x and y axes). In retrace's axes the horizontal plane is (x right,
// z forward): with c = -Rᵀ t the centre of B in A's frame, φ = atan2(c_x, c_z), in radians: 0 = straight ahead,
// positive = to the right (clockwise seen from above), ±π = behind.
double PlanarHeading(const Rigid3d& b_from_a);

namespace internal {
// The 2-parameter manifold of the planar refinement: θ ← θ + δ₀, t ← R_y(δ₁) t.
PoseManifold PlanarPoseManifold();
}  // namespace internal

}  // namespace retrace
