#pragma once

// Order statistics of measurements for the figures retrace prints (medians, percentiles of errors), and the
// bootstrap standard error of a difference of medians that tests compare two estimators by.

#include <cstddef>
#include <cstdint>
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

// The standard error of median(a) - median(b) over paired samples (a[i] and b[i] measured on one frame), by a
// moving-block bootstrap (Künsch 1989): the first min(a.size(), b.size()) pairs resampled as blocks of `block`
// consecutive pairs drawn with replacement, `resamples` times, from a generator seeded with `seed` (the same answer on
// every run). Blocks keep the runs in which errors of consecutive frames come; block 1 is the ordinary paired
// bootstrap. 0 for fewer than 2 · block pairs, block 0 or fewer than 2 resamples.
double PairedMedianDifferenceStandardError(const std::vector<double>& a, const std::vector<double>& b, size_t block,
                                           int resamples = 2000, uint32_t seed = 1);

}  // namespace retrace
