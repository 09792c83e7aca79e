#pragma once

// The minimal 5-point solver of calibrated relative pose: the essential matrices E with f_Bᵀ E f_A = 0 for five
// correspondences of unit bearing vectors (f_A, f_B), at most 10 real solutions.
//
// Method of Stewénius, Engels and Nistér, "Recent developments on direct relative orientation", ISPRS Journal of
// Photogrammetry and Remote Sensing 60(4), 2006 (the Gröbner-basis / action-matrix formulation of Nistér, "An
// efficient solution to the five-point relative pose problem", PAMI 26(6), 2004):
//  1. the five epipolar constraints leave E in a 4-dimensional null space, E = x X + y Y + z Z + W;
//  2. det(E) = 0 and the trace constraint 2 E Eᵀ E - trace(E Eᵀ) E = 0 give 10 cubic equations in (x, y, z);
//  3. Gauss-Jordan elimination of their 10 cubic monomials expresses each cubic monomial by the 10 monomials of
//     degree ≤ 2 (a basis of the quotient ring for generic data);
//  4. the 10 x 10 action matrix of the multiplication by x in that basis has the basis monomials evaluated at
//     each solution as its eigenvectors: real eigenvalues give the real solutions.
//
// Written in retrace (no Eigen containers cross a library boundary; see README "Sanitizers").

#include <vector>

#include "retrace/util/types.h"

namespace retrace {

// Appends to `essentials` the essential matrices (unit Frobenius norm, sign arbitrary) of the five
// correspondences bearings_a[i] <-> bearings_b[i] (f_Bᵀ E f_A = 0). Degenerate samples (a null space of
// dimension above 4, no real solution) append nothing.
void SolveEssentialFivePoint(const Vector3d bearings_a[5], const Vector3d bearings_b[5],
                             std::vector<Matrix3d>* essentials);

}  // namespace retrace
