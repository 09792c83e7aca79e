// Cost of the path law per frame (single thread): PathTracker::Update with the offset filter over its window
// (offset.process_sigma 0.05: the robust combination of the frames carried by the commanded motion) against each
// frame's own offset (offset.process_sigma 0), in the same run. Argument: speed in dm/s at 10 frames/s — 80 (8 m/s:
// the 20 m window holds 25 frames) and 20 (2 m/s: the window is held to its 64-frame cap).
//
//   build/src/retrace/control/bench_control_path_tracking --benchmark_repetitions=5
//       --benchmark_report_aggregates_only=true     (one command)

#include <cmath>
#include <random>

#include <benchmark/benchmark.h>

#include "retrace/control/path_tracking.h"

namespace retrace {
namespace {

void RunTracker(benchmark::State& state, double process_sigma) {
  PathTrackingOptions options;
  options.offset.process_sigma = process_sigma;
  options.max_speed = state.range(0) / 10.0;
  PathTracker tracker(options);
  std::mt19937 random(3);
  std::normal_distribution<double> noise(0.0, 0.05);
  PathTrackingInput input;
  input.tracking = true;
  input.confidence = 1.0;
  input.metric = true;
  input.lateral_sigma_m = 0.05;
  input.dt = 0.1;
  size_t frame = 0;
  for (auto _ : state) {
    input.lateral_m = 0.3 * std::sin(0.01 * static_cast<double>(frame++)) + noise(random);
    input.heading_error_rad = 0.01 * noise(random);
    benchmark::DoNotOptimize(tracker.Update(input));
  }
}

void BM_PathTrackerFiltered(benchmark::State& state) { RunTracker(state, 0.05); }
BENCHMARK(BM_PathTrackerFiltered)->Arg(80)->Arg(20)->Unit(benchmark::kMicrosecond);

void BM_PathTrackerOwnOffset(benchmark::State& state) { RunTracker(state, 0.0); }
BENCHMARK(BM_PathTrackerOwnOffset)->Arg(80)->Arg(20)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace retrace
