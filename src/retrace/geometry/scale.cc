#include "retrace/geometry/scale.h"

#include <algorithm>
#include <cmath>

namespace retrace {
namespace {

double MedianInPlace(std::vector<double>* values) {
  const size_t n = values->size();
  auto mid = values->begin() + n / 2;
  std::nth_element(values->begin(), mid, values->end());
  if (n % 2 == 1) return *mid;
  const double upper = *mid;
  const double lower = *std::max_element(values->begin(), mid);
  return 0.5 * (lower + upper);
}

}  // namespace

ScaleEstimate EstimateScaleFromDistances(const std::vector<double>& distances_1,
                                         const std::vector<double>& distances_2, int min_votes) {
  ScaleEstimate estimate;
  if (distances_1.size() != distances_2.size()) return estimate;
  std::vector<double> log_votes;
  log_votes.reserve(distances_1.size());
  for (size_t i = 0; i < distances_1.size(); ++i) {
    const double d1 = distances_1[i], d2 = distances_2[i];
    if (d1 > 0.0 && d2 > 0.0 && std::isfinite(d1) && std::isfinite(d2)) log_votes.push_back(std::log(d1 / d2));
  }
  estimate.num_votes = static_cast<int>(log_votes.size());
  if (estimate.num_votes < std::max(1, min_votes)) return estimate;
  // The median of the ratios equals exp(median of log-ratios) for odd counts; logs also make the spread symmetric.
  const double log_scale = MedianInPlace(&log_votes);
  for (double& v : log_votes) v = std::abs(v - log_scale);
  estimate.log_mad = MedianInPlace(&log_votes);
  estimate.scale = std::exp(log_scale);
  estimate.success = true;
  return estimate;
}

ScaleEstimate EstimateScale(const std::vector<Vector3d>& points_1, const Rigid3d& shared_from_1,
                            const std::vector<Vector3d>& points_2, const Rigid3d& shared_from_2, int min_votes) {
  if (points_1.size() != points_2.size()) return ScaleEstimate();
  std::vector<double> d1(points_1.size()), d2(points_2.size());
  for (size_t i = 0; i < points_1.size(); ++i) {
    d1[i] = (shared_from_1 * points_1[i]).norm();
    d2[i] = (shared_from_2 * points_2[i]).norm();
  }
  return EstimateScaleFromDistances(d1, d2, min_votes);
}

}  // namespace retrace
