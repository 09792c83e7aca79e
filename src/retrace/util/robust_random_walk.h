#pragma once

// One quantity x observed several times from places it drifts away from, some observations wrong: the robust
// combination behind an arc's metric scale (repeat/taught_path.h, its neighbours' ground fits carried through the
// node scales) and the path tracker's lateral offset (control/path_tracking.h, the recent frames' offsets carried by
// the vehicle's motion).
//
// Each observation y_j is carried from its own place to x's:
//   y_j = x + (the walk between x's place and y_j's) + e_j,   e_j ~ (1 - p) N(0, σ_j²) + p U(L).
// Observations on the same side of x share their walk up to the nearer one, and observations of one group (the
// frames whose poses rest on one arc's reconstruction and features) share a part ρ of their errors, so the right
// observations' covariance is
//   C_ij = min(v_i, v_j) [same side] + ρ σ_i σ_j [same group, i ≠ j] + δ_ij σ_j²,   v_j the variance of y_j's walk:
// a run of frames of one group counts as one observation with its σ where ρ = 1 and as independent ones where ρ = 0.
// The estimate is this Gaussian-uniform mixture solved by expectation-maximisation (the inlier-outlier model of
// MLESAC, Torr & Zisserman 2000) with generalised least squares inside: started at the observation of highest mixture
// likelihood (a mode, not the median: wrong observations come in runs), each step weighs every observation by its
// responsibility w_j (E) and takes x = 1ᵀC_w⁻¹y / 1ᵀC_w⁻¹1 with σ_j / √w_j in place of σ_j (M); its variance is
// 1 / 1ᵀC_w⁻¹1.

#include <cstddef>
#include <cstdint>
#include <deque>
#include <string>
#include <vector>

namespace retrace {

struct CarriedObservation {
  double value = 0.0;
  double sigma = 0.0;             // σ_j of the observation when it is right
  double carried_variance = 0.0;  // v_j
  int side = 0;                   // 0: at x's place; +1 / -1: after / before it
  int64_t group = -1;             // observations of one group >= 0 share a part of their errors; -1: none
};

struct CombinedObservation {
  bool valid = false;  // false without observations
  double value = 0.0;
  double sigma = 0.0;  // posterior, with the observations judged right
  int inliers = 0;     // observations judged right (responsibility > 0.5)
};

// `outlier_probability` p in [0, 1), `outlier_range` L > 0 and `shared_correlation` ρ in [0, 1) as above.
CombinedObservation CombineCarriedObservations(const std::vector<CarriedObservation>& observations,
                                               double outlier_probability, double outlier_range,
                                               double shared_correlation = 0.0);

// The recent observations of a quantity that walks along a travelled distance (a vehicle's lateral offset from its
// path), combined at the latest one: each carried over the distance since it was made as a random walk of
// `process_sigma` per √(unit of distance), combined by CombineCarriedObservations. The path tracker's offset
// (control/path_tracking.h) and the localizer's lateral offset (repeat/localizer.h) keep one each.
struct ObservationWindowOptions {
  // Observations more than `window` units of distance behind the latest are forgotten, and all but the last
  // `max_observations` (a vehicle standing still adds observations but no distance).
  double window = 20.0;
  size_t max_observations = 64;
  double process_sigma = 0.05;
  // An observation's σ is at least this; it is wrong with `outlier_probability`, uniform over `outlier_range`.
  double min_sigma = 0.02;
  double outlier_probability = 0.1;
  double outlier_range = 10.0;
  // ρ: the correlation of the errors of two observations of one group (Add's `group`; 0: independent). The
  // frames' own offsets from the taught path correlate by about 0.6 on one arc (PathTrackingOptions::offset).
  double shared_correlation = 0.0;

  bool Check(std::string* error = nullptr) const;
};

class ObservationWindow {
 public:
  explicit ObservationWindow(const ObservationWindowOptions& options = {}) : options_(options) {}
  // `distance`: where the observation was made (never less than the last one's); `group` >= 0: the observations
  // of one group share a part of their errors (ObservationWindowOptions::shared_correlation), -1: none.
  void Add(double distance, double value, double sigma, int64_t group = -1);
  // The observations combined at the latest one's distance; invalid when there is none.
  CombinedObservation Combine() const;
  void Clear() { observations_.clear(); }
  size_t size() const { return observations_.size(); }
  bool empty() const { return observations_.empty(); }

 private:
  struct Observation {
    double distance, value, sigma;
    int64_t group;
  };
  ObservationWindowOptions options_;
  std::deque<Observation> observations_;
};

}  // namespace retrace
