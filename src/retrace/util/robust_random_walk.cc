#include "retrace/util/robust_random_walk.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>
#include <Eigen/Core>

namespace retrace {

CombinedObservation CombineCarriedObservations(const std::vector<CarriedObservation>& observations,
                                               double outlier_probability, double outlier_range,
                                               double shared_correlation) {
  CombinedObservation combined;
  const int n = static_cast<int>(observations.size());
  if (n == 0 || !(outlier_range > 0) || !(shared_correlation >= 0 && shared_correlation < 1)) return combined;
  const double p = outlier_probability;
  const double outlier_density = p / outlier_range;  // p · U(L)
  Eigen::VectorXd y(n), own_variance(n);
  Eigen::MatrixXd shared(n, n);  // the walk shared with the other observations on the same side
  Eigen::MatrixXd correlation = Eigen::MatrixXd::Identity(n, n);  // of the errors: ρ within a group
  for (int i = 0; i < n; ++i) {
    y(i) = observations[i].value;
    own_variance(i) = observations[i].sigma * observations[i].sigma;
    for (int j = 0; j < n; ++j) {
      const bool same_side = observations[i].side != 0 && observations[i].side == observations[j].side;
      shared(i, j) =
          same_side ? std::min(observations[i].carried_variance, observations[j].carried_variance) : 0.0;
      const bool same_group = observations[i].group >= 0 && observations[i].group == observations[j].group;
      if (j != i && same_group) correlation(i, j) = shared_correlation;
    }
  }
  // Responsibilities of the Gaussian component (E step) and the mixture's log-likelihood at x.
  const auto responsibilities = [&](double x, Eigen::VectorXd* w) {
    double log_likelihood = 0.0;
    for (int i = 0; i < n; ++i) {
      const double variance = shared(i, i) + own_variance(i);
      const double r = y(i) - x;
      const double inlier = (1 - p) * std::exp(-0.5 * r * r / variance) / std::sqrt(2 * M_PI * variance);
      if (w != nullptr) (*w)(i) = inlier / (inlier + outlier_density);
      log_likelihood += std::log(inlier + outlier_density);
    }
    return log_likelihood;
  };
  double x = y(0);
  double best = -std::numeric_limits<double>::infinity();
  for (int i = 0; i < n; ++i) {
    const double log_likelihood = responsibilities(y(i), nullptr);
    if (log_likelihood > best) {
      best = log_likelihood;
      x = y(i);
    }
  }
  Eigen::VectorXd w(n);
  double information = 0.0;
  constexpr int kMaxIterations = 30;
  for (int iteration = 0; iteration < kMaxIterations; ++iteration) {
    responsibilities(x, &w);
    // Each observation's σ_j / √w_j in the errors' covariance: its square on the diagonal, ρ times the product
    // within a group.
    const Eigen::VectorXd scaled = (own_variance.array() / w.array().max(1e-9)).sqrt();
    const Eigen::MatrixXd covariance = shared + correlation.cwiseProduct(scaled * scaled.transpose());
    const Eigen::LDLT<Eigen::MatrixXd> ldlt(covariance);
    const Eigen::VectorXd gain = ldlt.solve(Eigen::VectorXd::Ones(n));  // C_w⁻¹ 1
    information = gain.sum();
    if (!(information > 0)) return combined;
    const double next = gain.dot(y) / information;
    const bool converged = std::abs(next - x) < 1e-9;
    x = next;
    if (converged) break;
  }
  responsibilities(x, &w);
  combined.valid = std::isfinite(x);
  combined.value = x;
  combined.sigma = std::sqrt(1.0 / information);
  combined.inliers = static_cast<int>((w.array() > 0.5).count());
  return combined;
}

bool ObservationWindowOptions::Check(std::string* error) const {
  const auto fail = [&](const std::string& message) {
    if (error != nullptr) *error = message;
    return false;
  };
  if (!(window >= 0) || max_observations < 1) return fail("window must be >= 0 and max_observations >= 1");
  if (!(process_sigma >= 0) || !(min_sigma > 0)) return fail("process_sigma must be >= 0 and min_sigma positive");
  if (!(outlier_probability >= 0) || !(outlier_probability < 1) || !(outlier_range > 0)) {
    return fail("outlier_probability must be in [0, 1) and outlier_range positive");
  }
  if (!(shared_correlation >= 0) || !(shared_correlation < 1)) return fail("shared_correlation must be in [0, 1)");
  return true;
}

void ObservationWindow::Add(double distance, double value, double sigma, int64_t group) {
  observations_.push_back({distance, value, std::max(options_.min_sigma, sigma), group});
  while (distance - observations_.front().distance > options_.window ||
         observations_.size() > options_.max_observations) {
    observations_.pop_front();
  }
}

CombinedObservation ObservationWindow::Combine() const {
  if (observations_.empty()) return {};
  const double latest = observations_.back().distance;
  const double q2 = options_.process_sigma * options_.process_sigma;
  std::vector<CarriedObservation> carried;
  carried.reserve(observations_.size());
  for (const Observation& o : observations_) {
    const double behind = latest - o.distance;
    carried.push_back({o.value, o.sigma, q2 * behind, behind > 0 ? -1 : 0, o.group});
  }
  return CombineCarriedObservations(carried, options_.outlier_probability, options_.outlier_range,
                                    options_.shared_correlation);
}

}  // namespace retrace
