#include "retrace/geometry/p3p.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Eigenvalues>

namespace retrace {
namespace {

// Polynomials in v as coefficient arrays, index = power.
using Polynomial = std::array<double, 5>;  // up to the quartic

Polynomial Multiply(const Polynomial& a, const Polynomial& b) {
  Polynomial p{};
  for (int i = 0; i < 5; ++i) {
    for (int j = 0; i + j < 5; ++j) p[i + j] += a[i] * b[j];
  }
  return p;
}

Polynomial Add(const Polynomial& a, const Polynomial& b, double b_scale) {
  Polynomial p;
  for (int i = 0; i < 5; ++i) p[i] = a[i] + b_scale * b[i];
  return p;
}

double Evaluate(const Polynomial& p, double v) {
  double value = 0.0;
  for (int i = 4; i >= 0; --i) value = value * v + p[i];
  return value;
}

double EvaluateDerivative(const Polynomial& p, double v) {
  double value = 0.0;
  for (int i = 4; i >= 1; --i) value = value * v + i * p[i];
  return value;
}

// Up to 3 Newton steps on p from v, each kept only when it reduces |p(v)|.
double PolishRoot(const Polynomial& p, double v) {
  double residual = std::abs(Evaluate(p, v));
  for (int step = 0; step < 3 && residual > 0.0; ++step) {
    const double slope = EvaluateDerivative(p, v);
    if (slope == 0.0) break;
    const double next = v - Evaluate(p, v) / slope;
    const double next_residual = std::abs(Evaluate(p, next));
    if (!(next_residual < residual)) break;
    v = next;
    residual = next_residual;
  }
  return v;
}

// The largest real root of m³ + a m² + b m + c (Cardano; trigonometric form for three real roots), polished.
double LargestRealRootOfCubic(double a, double b, double c) {
  const double p = b - a * a / 3.0;
  const double q = 2.0 * a * a * a / 27.0 - a * b / 3.0 + c;
  const double discriminant = 0.25 * q * q + p * p * p / 27.0;
  double t;
  if (discriminant > 0.0) {
    const double root = std::sqrt(discriminant);
    t = std::cbrt(-0.5 * q + root) + std::cbrt(-0.5 * q - root);
  } else if (p < 0.0) {
    const double cosine = std::clamp(1.5 * q / p * std::sqrt(-3.0 / p), -1.0, 1.0);
    t = 2.0 * std::sqrt(-p / 3.0) * std::cos(std::acos(cosine) / 3.0);
  } else {
    t = 0.0;  // p = q = 0: triple root
  }
  const Polynomial cubic = {c, b, a, 1.0, 0.0};
  return PolishRoot(cubic, t - a / 3.0);
}

// Real parts of the roots of the quartic p by Ferrari's method: with v = y - p₃ / (4 p₄) the depressed quartic
// y⁴ + P y² + Q y + R factors, for a root m > 0 of the resolvent cubic 8 m³ + 8 P m² + (2 P² - 8 R) m - Q² (one
// exists when Q ≠ 0), into y² ∓ s y + P / 2 + m ± Q / (2 s) with s = √(2 m): two real quadratics. A complex pair
// contributes its real part once. Returns the number of roots written to roots[0..]; 0 when Q vanishes (or the
// leading coefficient), for the companion-matrix fallback.
int FerrariRealParts(const Polynomial& p, double roots[4]) {
  if (p[4] == 0.0) return 0;
  const double b = p[3] / p[4], c = p[2] / p[4], d = p[1] / p[4], e = p[0] / p[4];
  const double b2 = b * b;
  const double big_p = c - 3.0 * b2 / 8.0;
  const double big_q = d - 0.5 * b * c + b2 * b / 8.0;
  const double big_r = e - 0.25 * b * d + b2 * c / 16.0 - 3.0 * b2 * b2 / 256.0;
  const double m = LargestRealRootOfCubic(big_p, 0.25 * big_p * big_p - big_r, -big_q * big_q / 8.0);
  if (!(m > 0.0) || !std::isfinite(m)) return 0;
  const double s = std::sqrt(2.0 * m);
  int count = 0;
  for (const double sign : {1.0, -1.0}) {
    // y² + beta y + gamma = 0
    const double beta = -sign * s;
    const double gamma = 0.5 * big_p + m + sign * big_q / (2.0 * s);
    const double discriminant = beta * beta - 4.0 * gamma;
    if (discriminant >= 0.0) {
      // Stable pair: the root of larger magnitude first, the other from the product gamma.
      const double root = std::sqrt(discriminant);
      const double large = -0.5 * (beta + (beta >= 0.0 ? root : -root));
      roots[count++] = large - 0.25 * b;
      roots[count++] = (large != 0.0 ? gamma / large : 0.0) - 0.25 * b;
    } else {
      roots[count++] = -0.5 * beta - 0.25 * b;
    }
  }
  for (int i = 0; i < count; ++i) roots[i] = PolishRoot(p, roots[i]);
  return count;
}

// Real parts of the roots of p (degree ≤ 4; leading coefficients negligible against the largest are dropped):
// Ferrari's formula for a proper quartic, else the eigenvalues of the companion matrix, polished by Newton steps.
// Returns their number, written to roots[0..].
int RealPartsOfRoots(const Polynomial& p, double roots[4]) {
  double largest = 0.0;
  for (double c : p) largest = std::max(largest, std::abs(c));
  if (!(largest > 0.0) || !std::isfinite(largest)) return 0;
  int degree = 4;
  while (degree > 0 && std::abs(p[degree]) <= 1e-14 * largest) --degree;
  if (degree == 0) return 0;
  if (degree == 4) {
    const int count = FerrariRealParts(p, roots);
    if (count > 0) return count;
  }
  using Companion = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 4, 4>;  // on the stack
  Companion companion = Companion::Zero(degree, degree);
  for (int i = 0; i < degree; ++i) companion(0, i) = -p[degree - 1 - i] / p[degree];
  for (int i = 1; i < degree; ++i) companion(i, i - 1) = 1.0;
  const Eigen::EigenSolver<Companion> eigen(companion, /*computeEigenvectors=*/false);
  if (eigen.info() != Eigen::Success) return 0;
  for (int i = 0; i < degree; ++i) roots[i] = PolishRoot(p, eigen.eigenvalues()[i].real());
  return degree;
}

// Orthonormal frame (columns) of a triangle: first axis along a -> b, third along its normal. Returns false for a
// degenerate triangle.
bool TriangleFrame(const Vector3d& a, const Vector3d& b, const Vector3d& c, Matrix3d* frame) {
  const Vector3d ab = b - a;
  const Vector3d normal = ab.cross(c - a);
  const double ab_norm = ab.norm(), normal_norm = normal.norm();
  if (!(ab_norm > 0.0) || !(normal_norm > 1e-12 * ab_norm * (c - a).norm())) return false;
  const Vector3d e1 = ab / ab_norm;
  const Vector3d e3 = normal / normal_norm;
  frame->col(0) = e1;
  frame->col(1) = e3.cross(e1);
  frame->col(2) = e3;
  return true;
}

}  // namespace

void SolveP3P(const Vector3d points_in_world[3], const Vector3d bearings[3], std::vector<Rigid3d>* poses) {
  const Vector3d& p1 = points_in_world[0];
  const Vector3d& p2 = points_in_world[1];
  const Vector3d& p3 = points_in_world[2];
  // Sides of the world triangle opposite each point (Haralick 1994, Fig. 1) and the cosines of the angles
  // between the rays: a = |p2 p3| faces the angle α between rays 2 and 3, b = |p1 p3| faces β (rays 1, 3),
  // c = |p1 p2| faces γ (rays 1, 2).
  const double a2 = (p2 - p3).squaredNorm(), b2 = (p1 - p3).squaredNorm(), c2 = (p1 - p2).squaredNorm();
  const double cos_alpha = bearings[1].dot(bearings[2]);
  const double cos_beta = bearings[0].dot(bearings[2]);
  const double cos_gamma = bearings[0].dot(bearings[1]);
  if (!(a2 > 0.0) || !(b2 > 0.0) || !(c2 > 0.0) || !std::isfinite(a2 + b2 + c2)) return;
  if (!(std::abs(cos_beta) < 1.0)) return;

  // Law of cosines with s2 = u s1, s3 = v s1 and s1² = b² / (1 + v² - 2 v cos β) from side b:
  //   side a:  b² (u² + v² - 2 u v cos α) = a² (1 + v² - 2 v cos β)
  //   side c:  b² (1 + u² - 2 u cos γ)    = c² (1 + v² - 2 v cos β)
  // Their difference is linear in u: u D(v) = N(v) with K = (a² - c²) / b²,
  //   N(v) = (K - 1) v² - 2 K cos β v + (K + 1),   D(v) = 2 (cos γ - v cos α),
  // and side c times D² gives the quartic N² - 2 cos γ N D + D² - (c² / b²) (1 + v² - 2 v cos β) D² = 0.
  const double k = (a2 - c2) / b2;
  const Polynomial n = {k + 1.0, -2.0 * k * cos_beta, k - 1.0, 0.0, 0.0};
  const Polynomial d = {2.0 * cos_gamma, -2.0 * cos_alpha, 0.0, 0.0, 0.0};
  const Polynomial side_b = {1.0, -2.0 * cos_beta, 1.0, 0.0, 0.0};
  const Polynomial d2 = Multiply(d, d);
  Polynomial quartic = Add(Multiply(n, n), Multiply(n, d), -2.0 * cos_gamma);
  quartic = Add(quartic, d2, 1.0);
  quartic = Add(quartic, Multiply(side_b, d2), -c2 / b2);

  Matrix3d world_frame;
  if (!TriangleFrame(p1, p2, p3, &world_frame)) return;
  const Vector3d world_centroid = (p1 + p2 + p3) / 3.0;
  double roots[4];
  const int num_roots = RealPartsOfRoots(quartic, roots);
  for (int r = 0; r < num_roots; ++r) {
    const double v = roots[r];
    const double d_v = Evaluate(d, v);
    if (!(v > 0.0) || d_v == 0.0) continue;
    const double u = Evaluate(n, v) / d_v;
    const double side_b_v = Evaluate(side_b, v);
    if (!(u > 0.0) || !(side_b_v > 0.0)) continue;
    const double s1 = std::sqrt(b2 / side_b_v);
    const Vector3d x1 = s1 * bearings[0], x2 = u * s1 * bearings[1], x3 = v * s1 * bearings[2];
    Matrix3d camera_frame;
    if (!TriangleFrame(x1, x2, x3, &camera_frame)) continue;
    const Matrix3d rotation = camera_frame * world_frame.transpose();
    const Vector3d translation = (x1 + x2 + x3) / 3.0 - rotation * world_centroid;
    if (!rotation.allFinite() || !translation.allFinite()) continue;
    poses->emplace_back(rotation, translation);
  }
}

}  // namespace retrace
