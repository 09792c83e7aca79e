#pragma once

// Order statistics of measurements for the figures retrace prints (medians, percentiles of errors).

#include <vector>

namespace retrace {

// The q-quantile (q in [0, 1]) as the element of rank floor(q n) of the sorted values (the largest for q = 1);
// 0 for no values.
double Quantile(std::vector<double> values, double q);

// The median: the middle value, or the mean of the two middle values of an even count; 0 for no values.
double Median(std::vector<double> values);

// A robust standard deviation of `values` about `centre`: 1.4826 times their median absolute deviation from it (the
// σ of Gaussian values); 0 for no values.
double RobustSigmaAbout(const std::vector<double>& values, double centre);

}  // namespace retrace
