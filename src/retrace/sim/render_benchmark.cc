// Rendering speed of the built-in town at 320x240 with anti-aliasing (filtered textures + quincunx edge
// supersampling), sun shadows and noise: frames of the default teach drive, per thread count (the argument).
//   build/src/retrace/sim/bench_sim_render --benchmark_repetitions=5 --benchmark_report_aggregates_only=true

#include <benchmark/benchmark.h>

#include "retrace/sim/simulator.h"

namespace retrace {
namespace {

void BM_RenderTown320x240(benchmark::State& state) {
  Scenario scenario;
  scenario.camera.width = 320;
  scenario.camera.height = 240;
  scenario.render.antialiasing = 2;
  scenario.render.filter_textures = true;
  scenario.render.num_threads = static_cast<int>(state.range(0));
  auto sim = std::make_unique<Simulator>(scenario);
  SimFrame frame;
  size_t supersampled = 0;
  for (auto _ : state) {
    if (!sim->NextFrame(&frame)) {
      state.PauseTiming();
      sim = std::make_unique<Simulator>(scenario);
      state.ResumeTiming();
      sim->NextFrame(&frame);
    }
    benchmark::DoNotOptimize(frame.image.data);
    supersampled += sim->last_supersampled_pixels();
  }
  state.counters["aa_pixels"] = static_cast<double>(supersampled) / std::max<int64_t>(1, state.iterations());
  state.counters["fps"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_RenderTown320x240)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(3.0);

}  // namespace
}  // namespace retrace
