#pragma once

// Exhaustive nearest neighbours of binary descriptors by Hamming distance, both ways at once: what the ratio test
// and the cross-check of binary matching need (wide_baseline.h's MatchWideBaseline, Segvic 2009 §4.1).
//
// A relocalizing frame matches its ~800 ORB descriptors against those of up to 20 key-images (issue 16); with one
// pair at a time this scan was a sixth of a kidnapped start's first frame on the 4.8 km map, a quarter of its slowest
// ones. It is written four ways, one chosen at run time by what the CPU has; all four give the same answer, to the
// index (hamming_nearest_test.cc). 822 against 850 descriptors of 32 bytes (BM_HammingNearest, medians of one run):
// 9.0 ms portable, 1.01 ms POPCNT, 0.66 ms AVX2, 0.32 ms AVX-512 with eight distances per register; with sixteen
// 0.237 ms where the build before took 0.308 ms earlier the same hour (2026-12-07, medians of 7 repetitions).
//  - kPortable: one pair at a time, the compiler's portable bit count;
//  - kPopcnt: the same with the POPCNT instruction (x86-64 CPUs since 2008);
//  - kAvx2: four key-image descriptors per 256-bit register, the bits counted by a nibble table lookup (Mula,
//    Kurz and Lemire, "Faster population counts using AVX2 instructions", Computer Journal 2018);
//  - kAvx512: eight per 512-bit register with the VPOPCNTQ instruction (AVX-512 VPOPCNTDQ), the distances of two
//    such registers packed into one of sixteen 32-bit lanes, where the minima are kept.
// The vector kernels lay the train descriptors out word-major in blocks of four (AVX2) or sixteen (AVX-512, two
// registers of eight), so that one register holds the same 64-bit word of as many descriptors: a distance is then a
// sum of per-lane bit counts, with no horizontal sums. Each lane keeps its own best and second best; the lanes are
// merged at the end of each query row (the lowest index wins a tie, as in a scan in order).

#include <vector>

#include <opencv2/core.hpp>

namespace retrace {

// For every query descriptor: the nearest train descriptor (-1 without any), its distance and the second-nearest
// distance (std::numeric_limits<int>::max() when there is none; equal to the nearest's when two are as near). For
// every train descriptor: the nearest query descriptor (-1 without any) and its distance. Ties keep the lowest index.
struct HammingNearest {
  std::vector<int> best, best_d, second_d;             // per query
  std::vector<int> best_query_of_train, best_query_d;  // per train
};

enum class HammingKernel { kAuto, kPortable, kPopcnt, kAvx2, kAvx512 };

// Whether this build and this CPU can run the kernel (kAuto and kPortable always).
bool HammingKernelAvailable(HammingKernel kernel);

// The fastest kernel available (what kAuto runs).
HammingKernel BestHammingKernel();

// query and train: CV_8U rows of 8, 16, 24 or 32 bytes, the same for both. A kernel not available throws
// std::invalid_argument.
HammingNearest FindHammingNearest(const cv::Mat& query, const cv::Mat& train,
                                  HammingKernel kernel = HammingKernel::kAuto);

}  // namespace retrace
