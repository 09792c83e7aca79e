#pragma once

// Quality of a two-view geometry: the conservative reprojection error bound σ_p of Segvic et al. 2009, §4.5.
//
// Model (eq. 1): the 2n reprojection residual components Δ_ix, Δ_iy of the n inliers are independent N(0, σ̂²).
// Then Z = Σ_i (Δ_ix² + Δ_iy²) / σ̂² is χ² with 2n degrees of freedom (eqs. 3-4), and the smallest bound σ_p with
// P(σ̂ > σ_p) <= p is (eqs. 2, 5, 6)
//
//     σ_p² = Σ_i (Δ_ix² + Δ_iy²) / F⁻¹_χ²(p; 2n),        p = 0.05 by default.
//
// For large n the quantile F⁻¹_χ²(p; 2n) tends to 2n, so σ_p tends to the RMS of the residual components; for small
// n the quantile is much smaller than 2n, which penalises geometries supported by few points.
//
// retrace measures the residuals in ONE image, as the paper does (2n components): the second image of the pair
// (image B of `b_from_a`), in pixels. For bearing vectors the residual is the angular offset between the observed
// bearing and the reprojected triangulated point in the tangent plane of the observed bearing, multiplied by the
// camera's FocalLength(); for a perspective camera near the image centre this equals the pixel residual.
//
// The quantile is on the hot path (every frame of teach and repeat evaluates several geometries), so a table of
// F⁻¹_χ²(p; 2n) is precomputed once per probability for n = 1..kTableSize and the Boost.Math quantile is only called
// beyond it.

#include <vector>

#include "retrace/util/types.h"

namespace retrace {

// F⁻¹_χ²(p; 2n): the p-quantile of the chi-square distribution with 2n degrees of freedom. `num_points` >= 1,
// 0 < p < 1. Served from a precomputed table for the common probability p = 0.05 and small n; thread-safe.
double ChiSquareQuantile2n(double p, int num_points);

// Segvic 2009, eq. (6): σ_p from the sum of squared residual components of `num_points` points (2 * num_points
// components). Returns +infinity when num_points < 1.
double SigmaPFromSumSquares(double sum_squared_residuals, int num_points, double p = 0.05);

// Same from the 2D residual vectors (pixels), one per point.
double SigmaP(const std::vector<Vector2d>& residuals, double p = 0.05);

}  // namespace retrace
