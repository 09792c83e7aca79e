#pragma once

// The heading the robot drives towards its subgoal, smoothed over observations (Booij 2007 §B.4): "a recency
// weighted averaging filter is used which takes into account previous estimates of φ", and "if the robot can not find
// a heading for 10 observations in a row it will try to relocalize".
//
// Headings are angles (radians, PlanarHeading: 0 = ahead, positive = right), so they are averaged as unit vectors:
// the filter keeps v ← (1 − w) v + w (sin φ, cos φ) (an exponentially decaying weight for older estimates) and
// reports atan2 of v. Averaging the numbers instead would turn −3.1 and 3.1 (both almost behind) into 0 (ahead).
//
//     estimate φ_k ──> u_k = (sin φ_k, cos φ_k) ──> v_k = (1 − w) v_{k−1} + w u_k ──> φ̂_k = atan2(v_k)
//     no estimate  ──> v unchanged, misses + 1 (relocalize at max_misses in a row)

#include <optional>
#include <string>

#include "retrace/util/types.h"

namespace retrace {

struct HeadingFilterOptions {
  // w: weight of the newest estimate (1 = no smoothing). The paper gives no value; 0.5 halves an old estimate's
  // weight at each observation.
  double new_weight = 0.5;
  // Observations in a row without a heading after which the robot relocalizes (Booij 2007 §B.4: 10).
  int max_misses = 10;

  bool Check(std::string* error = nullptr) const;
};

class HeadingFilter {
 public:
  explicit HeadingFilter(const HeadingFilterOptions& options = {});

  // One observation: a heading estimate in radians, or none when it could not be estimated.
  void Update(std::optional<double> heading);
  // The smoothed heading in (−π, π]; none before the first estimate (or after Reset) and when the estimates cancel
  // out exactly.
  std::optional<double> heading() const;
  // Observations in a row without an estimate.
  int misses() const { return misses_; }
  // The paper's recovery: max_misses observations in a row without a heading.
  bool NeedsRelocalization() const { return misses_ >= options_.max_misses; }
  // Forgets every estimate (after a relocalization or a new subgoal far from the last).
  void Reset();

 private:
  HeadingFilterOptions options_;
  Vector2d sum_ = Vector2d::Zero();  // v: (sin, cos) average
  bool has_estimate_ = false;
  int misses_ = 0;
};

}  // namespace retrace
