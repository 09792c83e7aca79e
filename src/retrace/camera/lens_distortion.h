#pragma once

// Radial-tangential lens distortion on normalized image coordinates, shared by the perspective and the unified
// (Mei) camera models.
//
// The forward model is OpenCV's "plumb bob" (Brown-Conrady) polynomial: for an ideal point m = (x, y) with
// r^2 = x^2 + y^2,
//   x_d = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2)
//   y_d = y (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y^2) + 2 p2 x y.
// It has no closed-form inverse. Segvic 2009 (§4.3) keeps a separate fitted polynomial for the correction
// direction; here that fitted inverse (radial part only) is the starting point of a few Gauss-Newton steps on the
// forward model, which makes both directions agree to machine precision wherever the model is invertible.

#include <array>

#include "retrace/util/types.h"

namespace retrace {

struct LensDistortion {
  double k1 = 0.0, k2 = 0.0, k3 = 0.0;  // radial
  double p1 = 0.0, p2 = 0.0;            // tangential

  bool IsZero() const { return k1 == 0 && k2 == 0 && k3 == 0 && p1 == 0 && p2 == 0; }
};

// Coefficients (c1, c2, c3) of the fitted inverse radial polynomial r_u = r_d (1 + c1 r_d^2 + c2 r_d^4 + c3 r_d^6).
using InverseRadialPolynomial = std::array<double, 3>;

// Ideal -> distorted normalized coordinates (the polynomial above).
Vector2d ApplyLensDistortion(const LensDistortion& distortion, const Vector2d& ideal);

// Least-squares fit of the inverse radial polynomial over ideal radii (0, max_ideal_radius]. The range is cut where
// the forward radial map stops increasing (a lens model is only invertible up to there).
InverseRadialPolynomial FitInverseRadialPolynomial(const LensDistortion& distortion, double max_ideal_radius);

// Distorted -> ideal normalized coordinates: the fitted inverse as a start, then Gauss-Newton on the forward model.
// Returns false (and the last iterate) when the iteration does not reach |ApplyLensDistortion(ideal) - distorted|
// < 1e-10, i.e. where the model is not invertible (far outside the calibrated image area).
bool RemoveLensDistortion(const LensDistortion& distortion, const InverseRadialPolynomial& inverse,
                          const Vector2d& distorted, Vector2d* ideal);

}  // namespace retrace
