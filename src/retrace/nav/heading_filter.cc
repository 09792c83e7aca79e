#include "retrace/nav/heading_filter.h"

#include <cmath>
#include <stdexcept>

namespace retrace {

bool HeadingFilterOptions::Check(std::string* error) const {
  const auto fail = [&](const char* message) {
    if (error != nullptr) *error = message;
    return false;
  };
  if (!(new_weight > 0 && new_weight <= 1)) return fail("new_weight must lie in (0, 1]");
  if (max_misses < 1) return fail("max_misses must be at least 1");
  return true;
}

HeadingFilter::HeadingFilter(const HeadingFilterOptions& options) : options_(options) {
  std::string error;
  if (!options_.Check(&error)) throw std::invalid_argument("HeadingFilterOptions: " + error);
}

void HeadingFilter::Update(std::optional<double> heading) {
  if (!heading || !std::isfinite(*heading)) {
    ++misses_;
    return;
  }
  misses_ = 0;
  const Vector2d unit(std::sin(*heading), std::cos(*heading));
  // Booij 2007 §B.4: recency-weighted average; the first estimate is taken as it is.
  sum_ = has_estimate_ ? Vector2d((1.0 - options_.new_weight) * sum_ + options_.new_weight * unit) : unit;
  has_estimate_ = true;
}

std::optional<double> HeadingFilter::heading() const {
  if (!has_estimate_ || !(sum_.norm() > 1e-12)) return std::nullopt;
  return std::atan2(sum_.x(), sum_.y());
}

void HeadingFilter::Reset() {
  sum_ = Vector2d::Zero();
  has_estimate_ = false;
  misses_ = 0;
}

}  // namespace retrace
