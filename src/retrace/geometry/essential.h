#pragma once

// Essential matrix on unit bearing vectors: construction from a pose, decomposition with the cheirality test, and
// the Sampson error on the sphere.
//
// For the relative pose b_from_a (x_B = R x_A + t) the essential matrix is E = [t]ₓ R and every correspondence of
// unit bearings (f_A, f_B) satisfies the epipolar constraint f_Bᵀ E f_A = 0 (Hartley & Zisserman 2003, §9.6).

#include <vector>

#include "retrace/util/types.h"

namespace retrace {

// Skew-symmetric matrix [v]ₓ with [v]ₓ w = v × w.
Matrix3d CrossProductMatrix(const Vector3d& v);

// Rotation by the axis-angle vector w (Rodrigues); I + [w]ₓ for |w| below 1e-12.
Matrix3d ExpSO3(const Vector3d& w);

// E = [t]ₓ R for b_from_a.
Matrix3d EssentialFromPose(const Rigid3d& b_from_a);

// The four (R, t) with E ∝ [t]ₓ R and |t| = 1 (Hartley & Zisserman 2003, Result 9.19): (U W Vᵀ | ±u₃) and
// (U Wᵀ Vᵀ | ±u₃). Returns false when E is not finite or has rank < 2.
bool DecomposeEssential(const Matrix3d& e, Rigid3d poses[4]);

// Squared Sampson error of a correspondence on the sphere, in radians²: the first-order approximation of the squared
// angular distance (summed over both images) to the closest correspondence that satisfies the epipolar constraint.
// The gradients of f_Bᵀ E f_A are projected onto the tangent planes of the bearings, which makes this the usual
// Sampson error for bearings near the optical axis and keeps it meaningful for omnidirectional bearings.
double SampsonErrorSquared(const Matrix3d& e, const Vector3d& bearing_a, const Vector3d& bearing_b);

// Signed version (sign of f_Bᵀ E f_A), used as a least-squares residual.
double SampsonResidual(const Matrix3d& e, const Vector3d& bearing_a, const Vector3d& bearing_b);

}  // namespace retrace
