#include "retrace/geometry/sigma_p.h"

#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <mutex>
#include <unordered_map>

#include <boost/math/distributions/chi_squared.hpp>

namespace retrace {
namespace {

// Table size: geometries of the map have tens to a few hundred inliers; beyond that Boost is called directly.
constexpr int kTableSize = 2048;
constexpr double kDefaultP = 0.05;

double BoostQuantile(double p, int num_points) {
  const boost::math::chi_squared_distribution<double> chi2(2.0 * num_points);
  return boost::math::quantile(chi2, p);
}

struct QuantileTable {
  explicit QuantileTable(double p) : values(kTableSize + 1) {
    values[0] = 0.0;
    for (int n = 1; n <= kTableSize; ++n) values[n] = BoostQuantile(p, n);
  }
  std::vector<double> values;  // values[n] = F⁻¹_χ²(p; 2n)
};

const QuantileTable& DefaultTable() {
  static const QuantileTable table(kDefaultP);  // thread-safe initialisation (C++11 magic statics)
  return table;
}

// Tables for other probabilities, built on first use.
const QuantileTable& TableFor(double p) {
  static std::mutex mutex;
  static std::unordered_map<double, std::unique_ptr<QuantileTable>> tables;
  std::lock_guard<std::mutex> lock(mutex);
  auto& table = tables[p];
  if (!table) table = std::make_unique<QuantileTable>(p);
  return *table;
}

}  // namespace

double ChiSquareQuantile2n(double p, int num_points) {
  if (num_points < 1 || !(p > 0.0 && p < 1.0)) return std::numeric_limits<double>::quiet_NaN();
  if (num_points > kTableSize) return BoostQuantile(p, num_points);
  if (p == kDefaultP) return DefaultTable().values[num_points];
  return TableFor(p).values[num_points];
}

double SigmaPFromSumSquares(double sum_squared_residuals, int num_points, double p) {
  if (num_points < 1) return std::numeric_limits<double>::infinity();
  // Segvic 2009, eq. (6): σ_p² = Σ_i (Δ_ix² + Δ_iy²) / F⁻¹_χ²(p; 2n).
  return std::sqrt(sum_squared_residuals / ChiSquareQuantile2n(p, num_points));
}

double SigmaP(const std::vector<Vector2d>& residuals, double p) {
  double sum = 0.0;
  for (const Vector2d& r : residuals) sum += r.squaredNorm();
  return SigmaPFromSumSquares(sum, static_cast<int>(residuals.size()), p);
}

}  // namespace retrace
