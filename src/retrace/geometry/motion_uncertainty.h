#pragma once

// How well a two-view geometry's correspondences determine its motion: the covariance of the rotation and of the
// translation direction, to first order (issue 18: teach writes no geometry it cannot support).
//
// σ_p (sigma_p.h) bounds how well the motion explains its points; it does not say whether another motion would
// explain them as well. On a weak pair — few points, most of them on the ground, a short baseline — the Sampson cost
// is nearly flat along some directions of the motion, and noise moves the estimate far along them: teach wrote
// tracked and gap arcs on a plane of fine ground texture 15-80 degrees off the truth with σ_p below 0.5 px
// (teacher_degenerate_test).
//
// Model: the Sampson residuals r_i of the n inliers (radians on the sphere, both images together; essential.h) are
// independent N(0, σ²) at the true motion. Linearised about the estimate on the 5-parameter manifold of the
// refinement (R ← exp(δ₀₁₂) R, t ← normalize(t + δ₃ b₁ + δ₄ b₂); relative_pose.h), the least-squares estimate has
// the covariance (Hartley & Zisserman 2003, §5.2.3, result 5.10)
//
//     Σ = σ² (Jᵀ J)⁻¹,      J = ∂r / ∂δ   (n x 5, central differences),
//     σ² = Σ r_i² / (n - 5)               (the residual variance, unbiased for 5 parameters),
//
// and δ₃, δ₄ are angles of the translation direction (radians, to first order), δ₀₁₂ of the rotation. The marginal
// blocks of Σ (rotation 3x3, direction 2x2) keep the correlation between them: in a narrow field of view a small
// rotation and a sideways translation look alike, and the direction's block says how much of the motion is
// uncertain for it. The largest standard deviation of each block (square root of its largest eigenvalue) is
// reported, and the half-angle of the block's confidence region along that axis: with σ estimated from the n - 5
// residual degrees of freedom, the region of d parameters at confidence c is the ellipsoid of radius
// sqrt(d F⁻¹(c; d, n - 5)) standard deviations (the linearised region of nonlinear least squares; Seber & Wild 1989,
// Nonlinear Regression, §5.2), 2.45 for the direction (d = 2) with many points, 2.63 with 26.
//
// The linearisation is the limit of the model: on weak pairs (few points, far away compared with the baseline) the
// cost is not quadratic over the spread of the estimates, and at the estimate it is often more curved than at the
// truth, so σ comes out too small, half the true spread and less (motion_uncertainty_test: of 78 draws 10 degrees or
// more off, the linear bound flagged 51). Whether a given direction is compatible with the data is therefore asked
// of the cost itself, by the likelihood-ratio region (Seber & Wild §5.3, more accurate than the linearised one for
// nonlinear models): the directions θ whose profile cost (the Sampson cost minimised over the rotation with the
// direction held at θ) exceeds the minimum by at most
//
//     S(θ) - S(θ̂) <= d σ² F⁻¹(c; d, n - 5),      d = 2.
//
// TestDirectionAt asks whether that region reaches a given angle from the estimate: it minimises the profile cost
// over the circle of directions at that angle (Levenberg-Marquardt on the rotation and the position on the circle,
// from eight starts around it). A region that extends beyond the circle anywhere crosses it when it is connected
// about the estimate; it is not when the pair has a second, separate solution (another minimum of the cost: a
// plane's two motions, planar_degeneracy.h, or the rotation traded for translation in a narrow field of view). The
// test tells the two apart: the region is connected when the circles at 1/4, 1/2 and 3/4 of the angle each hold a
// direction within it (continued inwards from the one found on the outer circle). A weak pair has a wide connected
// region; a pair with two solutions may have a narrow region about each.

#include <vector>

#include "retrace/util/types.h"

namespace retrace {

struct MotionUncertainty {
  int num_points = 0;   // inliers used
  double sigma_px = 0;  // residual standard deviation σ, in pixels (radians times the focal length)
  // Largest standard deviation of the rotation (about any axis) and of the translation direction, degrees.
  // Infinite when the inliers do not determine the motion at all (fewer than 6, or Jᵀ J singular).
  double rotation_sigma_deg = 0;
  double direction_sigma_deg = 0;
  // Half-angles of the confidence regions along those axes at the requested confidence, degrees (see above).
  double rotation_bound_deg = 0;
  double direction_bound_deg = 0;
};

// The uncertainty of `b_from_a` (x_B = R x_A + t, unit t) estimated from the correspondences bearings_a[i] <->
// bearings_b[i] with inlier_mask[i] set, and its confidence bounds at `confidence` (0 < confidence < 1).
// `focal_length_px` converts the residuals to pixels; σ is not taken below `min_sigma_px` (exact synthetic data would
// otherwise be certain).
MotionUncertainty EstimateMotionUncertainty(const std::vector<Vector3d>& bearings_a,
                                            const std::vector<Vector3d>& bearings_b,
                                            const std::vector<bool>& inlier_mask, const Rigid3d& b_from_a,
                                            double focal_length_px, double confidence = 0.95,
                                            double min_sigma_px = 0.01);

// Whether some translation direction `angle_deg` away from the estimate's lies in the likelihood-ratio confidence
// region of the direction at `confidence` (see above): the pair does not determine the direction within that angle.
struct DirectionTest {
  bool within_region = false;
  // The smallest increase of the Sampson cost over the circle, in units of σ², and the region's bound d F⁻¹(c; d,
  // n - 5) it is compared with. With fewer than 6 inliers nothing is determined: increase 0, within the region.
  double cost_increase = 0;
  double bound = 0;
  Vector3d direction = Vector3d::Zero();  // the direction on the circle where the increase is smallest
  // Within the region, and the region connects that direction to the estimate (see above): a weak pair, rather than
  // a second solution.
  bool connected = false;
};

DirectionTest TestDirectionAt(const std::vector<Vector3d>& bearings_a, const std::vector<Vector3d>& bearings_b,
                              const std::vector<bool>& inlier_mask, const Rigid3d& b_from_a, double focal_length_px,
                              double angle_deg, double confidence = 0.95, double min_sigma_px = 0.01);

}  // namespace retrace
