#include "retrace/util/statistics.h"

#include <algorithm>
#include <cmath>
#include <random>

namespace retrace {

double Quantile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  const size_t rank = std::min(values.size() - 1, static_cast<size_t>(std::max(0.0, q) * values.size()));
  std::nth_element(values.begin(), values.begin() + rank, values.end());
  return values[rank];
}

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  if (values.size() % 2 == 1) return *middle;
  return 0.5 * (*middle + *std::max_element(values.begin(), middle));
}

double RobustSigmaAbout(const std::vector<double>& values, double centre) {
  std::vector<double> deviations;
  deviations.reserve(values.size());
  for (const double v : values) deviations.push_back(std::abs(v - centre));
  return 1.4826 * Median(std::move(deviations));
}

double PairedMedianDifferenceStandardError(const std::vector<double>& a, const std::vector<double>& b, size_t block,
                                           int resamples, uint32_t seed) {
  const size_t n = std::min(a.size(), b.size());
  if (block == 0 || n < 2 * block || resamples < 2) return 0.0;
  std::mt19937 random(seed);
  std::uniform_int_distribution<size_t> block_start(0, n - block);
  std::vector<double> differences, resampled_a, resampled_b;
  differences.reserve(static_cast<size_t>(resamples));
  for (int r = 0; r < resamples; ++r) {
    resampled_a.clear();
    resampled_b.clear();
    while (resampled_a.size() < n) {
      const size_t first = block_start(random);
      for (size_t i = first; i < first + block && resampled_a.size() < n; ++i) {
        resampled_a.push_back(a[i]);
        resampled_b.push_back(b[i]);
      }
    }
    differences.push_back(Median(resampled_a) - Median(resampled_b));
  }
  // Their standard deviation, about their mean in a second pass (no cancellation when they hardly spread).
  double mean = 0.0;
  for (const double d : differences) mean += d;
  mean /= resamples;
  double sum_squares = 0.0;
  for (const double d : differences) sum_squares += (d - mean) * (d - mean);
  return std::sqrt(sum_squares / resamples);
}

}  // namespace retrace
