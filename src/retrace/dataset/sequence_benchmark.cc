// Speed of streaming a real KITTI sequence (PNG decode + gray conversion) through OpenSequence.
// Needs the shared data (kitti07); reports an error and does nothing when it is absent.

#include <filesystem>

#include <benchmark/benchmark.h>

#include "retrace/dataset/sequence.h"

namespace retrace {
namespace {

void BM_ReadKitti07Frame(benchmark::State& state) {
  const std::filesystem::path dir = std::filesystem::path(RETRACE_SHARED_DATA_DIR) / "kitti07";
  if (!std::filesystem::exists(dir)) {
    state.SkipWithError("shared data kitti07 not found");
    return;
  }
  std::unique_ptr<Sequence> sequence = OpenSequence(dir);
  for (auto _ : state) {
    std::optional<Frame> frame = sequence->Next();
    if (!frame) {
      sequence->Rewind();
      frame = sequence->Next();
    }
    benchmark::DoNotOptimize(frame->image.data);
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_ReadKitti07Frame)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace retrace
