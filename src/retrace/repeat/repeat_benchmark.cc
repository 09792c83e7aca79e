// Repeat throughput on kitti07 (single thread): map taught from the even frames, the odd frames localized one by one.
// The bootstrap frame (wide-baseline matching) is excluded from the timing; everything else a live run does per frame
// (pyramid, tracking, two current geometries, transfer, resumption, transitions, steering) is timed.
//
//   build/src/retrace/repeat/bench_repeat_repeat --benchmark_repetitions=5 --benchmark_report_aggregates_only=true

#include <filesystem>
#include <map>
#include <memory>

#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>

#include "retrace/camera/camera_io.h"
#include "retrace/dataset/sequence.h"
#include "retrace/image/image_utils.h"
#include "retrace/repeat/localizer.h"
#include "retrace/teach/teacher.h"

namespace retrace {
namespace {

struct Setup {
  std::unique_ptr<CameraModel> camera;
  Map map;
  std::vector<Frame> repeat_frames;
};

// Teach on the even frames and load the odd ones, at `width` (0 = native); cached per width.
const Setup* GetSetup(int width) {
  static std::map<int, std::unique_ptr<Setup>> cache;
  auto& entry = cache[width];
  if (entry) return entry.get();
  const std::filesystem::path kitti = std::filesystem::path(RETRACE_SHARED_DATA_DIR) / "kitti07";
  if (!std::filesystem::exists(kitti)) return nullptr;
  auto setup = std::make_unique<Setup>();
  std::unique_ptr<Sequence> sequence = OpenSequence(kitti);
  setup->camera = ReadCameraFile(*sequence->calibration_file(), sequence->image_size());
  if (width > 0) setup->camera = setup->camera->Scaled(static_cast<double>(width) / setup->camera->width());
  const auto resize = [&](Frame* frame) {
    if (frame->image.cols == setup->camera->width()) return;
    cv::Mat resized;
    ResizeToWidth(frame->image, setup->camera->width(), &resized);
    frame->image = resized;
  };
  Teacher teacher(*setup->camera, TeachOptions(), nullptr);
  SubsampledSequence even(OpenSequence(kitti), 2, 0);
  while (auto frame = even.Next()) {
    resize(&*frame);
    teacher.AddFrame(*frame);
  }
  teacher.Finish();
  setup->map = teacher.map();
  SubsampledSequence odd(OpenSequence(kitti), 2, 1);
  while (auto frame = odd.Next()) {
    resize(&*frame);
    setup->repeat_frames.push_back(*frame);
  }
  entry = std::move(setup);
  return entry.get();
}

void BM_RepeatKitti(benchmark::State& state) {
  const Setup* setup = GetSetup(static_cast<int>(state.range(0)));
  if (setup == nullptr) {
    state.SkipWithError("kitti07 not found");
    return;
  }
  int64_t frames = 0;
  int64_t tracked = 0;
  for (auto _ : state) {
    state.PauseTiming();
    Localizer localizer(setup->map, *setup->camera);
    localizer.SetStartArc(setup->map.arcs().front().id);
    localizer.ProcessFrame(setup->repeat_frames.front());
    state.ResumeTiming();
    for (size_t i = 1; i < setup->repeat_frames.size(); ++i) {
      const FrameResult result = localizer.ProcessFrame(setup->repeat_frames[i]);
      tracked += result.tracked;
      ++frames;
    }
  }
  state.SetItemsProcessed(frames);
  state.counters["tracked_per_frame"] = frames > 0 ? static_cast<double>(tracked) / frames : 0.0;
  state.counters["width"] = setup->camera->width();
}
// 0 = native 1226x370. (kitti07 resized to 320 px is 320x97: teach cannot build a connected map from it, so there is
// no 320 px figure on this data.)
BENCHMARK(BM_RepeatKitti)->Arg(0)->Unit(benchmark::kMillisecond)->Iterations(1);

}  // namespace
}  // namespace retrace
