#include "retrace/geometry/sigma_p.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

namespace retrace {
namespace {

// Lower tail of the chi-square CDF with an even number of degrees of freedom 2n, in closed form:
// P(Z < z) = 1 - exp(-z/2) Σ_{k<n} (z/2)^k / k!  (an independent check of the Boost quantile).
double ChiSquareCdfEven(double z, int n) {
  // Terms evaluated in the log domain: exp(-z/2) underflows for large n.
  const double half = 0.5 * z;
  double sum = 0.0;
  for (int k = 0; k < n; ++k) sum += std::exp(-half + k * std::log(half) - std::lgamma(k + 1.0));
  return 1.0 - sum;
}

TEST(SigmaP, QuantileMatchesClosedFormCdf) {
  for (int n : {1, 2, 5, 10, 50, 200, 1000}) {
    const double q = ChiSquareQuantile2n(0.05, n);
    EXPECT_NEAR(ChiSquareCdfEven(q, n), 0.05, 1e-9) << "n = " << n;
    const double q10 = ChiSquareQuantile2n(0.10, n);
    EXPECT_NEAR(ChiSquareCdfEven(q10, n), 0.10, 1e-9) << "n = " << n;
  }
  // One point, 2 degrees of freedom: F(z) = 1 - exp(-z/2) => z = -2 ln(0.95).
  EXPECT_NEAR(ChiSquareQuantile2n(0.05, 1), -2.0 * std::log(0.95), 1e-12);
  // Beyond the precomputed table.
  EXPECT_NEAR(ChiSquareCdfEven(ChiSquareQuantile2n(0.05, 3000), 3000), 0.05, 1e-6);
}

TEST(SigmaP, GrowsAsPointsBecomeFewerAtEqualResiduals) {
  // Every point has the same residual (1 px, 1 px): the RMS of the components is 1 px for every n.
  double previous = 0.0;
  for (int n : {1000, 300, 100, 30, 10, 5, 2, 1}) {
    const std::vector<Vector2d> residuals(n, Vector2d(1.0, 1.0));
    const double sigma = SigmaP(residuals);
    EXPECT_GT(sigma, 1.0) << "n = " << n;
    if (previous > 0.0) {
      EXPECT_GT(sigma, previous) << "n = " << n;
    }
    previous = sigma;
  }
}

TEST(SigmaP, TendsToRmsForManyPoints) {
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.7);
  for (int n : {2000, 5000, 20000}) {
    std::vector<Vector2d> residuals(n);
    double sum = 0.0;
    for (auto& r : residuals) {
      r = Vector2d(noise(rng), noise(rng));
      sum += r.squaredNorm();
    }
    const double rms = std::sqrt(sum / (2.0 * n));
    const double sigma = SigmaP(residuals);
    // σ_p / RMS = sqrt(2n / F⁻¹(0.05; 2n)) ≈ 1 + 1.645 / sqrt(4n) for large n (normal approximation of χ²).
    const double expected_ratio = 1.0 + 1.6449 / std::sqrt(4.0 * n);
    EXPECT_NEAR(sigma / rms, expected_ratio, 0.002) << "n = " << n;
    EXPECT_LT(sigma / rms, 1.03);
  }
}

TEST(SigmaP, MatchesFormulaAndConservativeCoverage) {
  // Segvic 2009, eq. (6) by hand for a small set.
  const std::vector<Vector2d> residuals = {{0.5, -0.2}, {1.0, 0.3}, {-0.4, 0.8}};
  const double sum = 0.25 + 0.04 + 1.0 + 0.09 + 0.16 + 0.64;
  EXPECT_NEAR(SigmaP(residuals), std::sqrt(sum / ChiSquareQuantile2n(0.05, 3)), 1e-12);
  // Coverage: with residuals ~ N(0, 1), σ_p exceeds the true σ = 1 in about 95 % of the trials.
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 1.0);
  int covered = 0;
  const int trials = 4000;
  for (int trial = 0; trial < trials; ++trial) {
    std::vector<Vector2d> r(8);
    for (auto& v : r) v = Vector2d(noise(rng), noise(rng));
    covered += SigmaP(r) >= 1.0;
  }
  EXPECT_NEAR(static_cast<double>(covered) / trials, 0.95, 0.015);
}

TEST(SigmaP, NoPointsIsInfinite) {
  EXPECT_TRUE(std::isinf(SigmaP({})));
  EXPECT_TRUE(std::isinf(SigmaPFromSumSquares(1.0, 0)));
}

}  // namespace
}  // namespace retrace
