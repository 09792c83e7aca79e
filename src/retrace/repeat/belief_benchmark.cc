// Cost of the place belief per frame (single thread): prediction by the motion model and the update with one
// placement, on a linear map of 60 arcs (the simulated drives' maps hold 36-63) and of 1000 arcs, with the belief
// concentrated (tracking) and spread (after a loss, speed unknown).
//
//   build/src/retrace/repeat/bench_repeat_belief --benchmark_repetitions=5 --benchmark_report_aggregates_only=true

#include <benchmark/benchmark.h>

#include "retrace/repeat/belief.h"
#include "retrace/repeat/linear_map_testing.h"

namespace retrace {
namespace {

// Argument: arcs of the map. The camera moves a quarter arc per frame, placed by an absolute pose every frame.
void BM_BeliefTracking(benchmark::State& state) {
  PlaceBelief belief(LinearMap(static_cast<int>(state.range(0)), {}, /*frames_per_arc=*/4));
  size_t frame = 0;
  double position = 0.0;
  for (auto _ : state) {
    ++frame;
    position += 0.25;
    if (position >= state.range(0) - 1) position = 0.0;
    belief.Predict(1);
    belief.Update({{static_cast<arc_t>(position), position - static_cast<int>(position), 0.03, 0.02}}, frame);
    benchmark::DoNotOptimize(belief.estimate());
  }
  state.counters["tracking"] = belief.estimate().tracking;
}
BENCHMARK(BM_BeliefTracking)->Arg(60)->Arg(1000)->Unit(benchmark::kMicrosecond);

// Argument: arcs of the map. No placements at all: the belief spreads with the speed unknown.
void BM_BeliefLost(benchmark::State& state) {
  PlaceBelief belief(LinearMap(static_cast<int>(state.range(0)), {}, /*frames_per_arc=*/4));
  size_t frame = 0;
  for (auto _ : state) {
    belief.Predict(1);
    belief.Update({}, ++frame);
    benchmark::DoNotOptimize(belief.estimate());
  }
}
BENCHMARK(BM_BeliefLost)->Arg(60)->Arg(1000)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace retrace
