#pragma once

// The minimal absolute-pose solver of a calibrated camera: the poses cam_from_world that see three world points
// along three unit bearing vectors, at most four.
//
// Grunert's solution (1841) as presented by Haralick, Lee, Ottenberg and Nölle, "Review and analysis of solutions
// of the three point perspective pose estimation problem", IJCV 13(3), 1994, §2.1: with s_i the distances of the
// points along their rays, s_2 = u s_1 and s_3 = v s_1, the law of cosines on the three sides of the world triangle
// gives two conics in (u, v); their difference is linear in u, and substituting u(v) into one conic leaves a
// quartic in v. Each real root gives the three points in the camera frame, and the rigid motion between the two
// congruent triangles is read from an orthonormal frame built on each (triad method).
//
// The quartic's coefficients are multiplied out from the conics in code rather than transcribed. Its roots come
// from the eigenvalues of the companion matrix, polished by Newton steps. As in Kneip's P3P (Kneip, Scaramuzza,
// Siegwart, CVPR 2011, which retrace used before through OpenGV) the real part of every root is used, so that a
// double root that noise turned into a complex pair still gives its pose; the robust loop that calls the solver
// scores every candidate.
//
// Written in retrace (no Eigen containers cross a library boundary; see README "Sanitizers").

#include <vector>

#include "retrace/util/types.h"

namespace retrace {

// Appends to `poses` every pose cam_from_world (x_cam = R x_world + t) that puts the three `points_in_world` at
// positive distances along the unit `bearings` (f_i ∝ R p_i + t). Degenerate triples (coincident or collinear
// points, parallel bearings) append nothing.
void SolveP3P(const Vector3d points_in_world[3], const Vector3d bearings[3], std::vector<Rigid3d>* poses);

}  // namespace retrace
