// Teach throughput on kitti07 (160 real frames), single thread, frames decoded and resized beforehand:
//   bench_teach_teacher --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
// The arguments are the working width (0 = native 1226 px) and whether teach tests each arc for a motion its pair
// does not determine (1, the default: TeachOptions::reject_planar_geometry and reject_undetermined_direction; 0:
// neither, to measure their cost in the same run). Skips when the shared data is absent.

#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "retrace/camera/camera_io.h"
#include "retrace/dataset/sequence.h"
#include "retrace/teach/teacher.h"

namespace retrace {
namespace {

struct KittiFrames {
  std::unique_ptr<CameraModel> camera;
  std::vector<Frame> frames;
};

// Loads kitti07 once per width; empty when the data is absent.
const KittiFrames& LoadKitti(int width) {
  static std::map<int, KittiFrames> cache;
  auto [it, inserted] = cache.try_emplace(width);
  if (!inserted) return it->second;
  const std::filesystem::path path = std::filesystem::path(RETRACE_SHARED_DATA_DIR) / "kitti07";
  if (!std::filesystem::exists(path)) return it->second;
  auto sequence = OpenSequence(path);
  it->second.camera = ReadCameraFile(*sequence->calibration_file(), sequence->image_size());
  double factor = 1.0;
  if (width > 0) {
    factor = static_cast<double>(width) / it->second.camera->width();
    it->second.camera = it->second.camera->Scaled(factor);
  }
  while (auto frame = sequence->Next()) {
    if (factor != 1.0) {
      cv::Mat resized;
      cv::resize(frame->image, resized, cv::Size(it->second.camera->width(), it->second.camera->height()), 0, 0,
                 cv::INTER_AREA);
      frame->image = resized;
    }
    it->second.frames.push_back(*frame);
  }
  return it->second;
}

void BM_TeachKitti(benchmark::State& state) {
  cv::setNumThreads(1);
  const KittiFrames& kitti = LoadKitti(static_cast<int>(state.range(0)));
  if (kitti.frames.empty()) {
    state.SkipWithError("shared data kitti07 not found");
    return;
  }
  TeachOptions options;
  options.reject_planar_geometry = options.reject_undetermined_direction = state.range(1) != 0;
  size_t key_images = 0;
  for (auto _ : state) {
    Teacher teacher(*kitti.camera, options, nullptr);
    for (const Frame& frame : kitti.frames) teacher.AddFrame(frame);
    teacher.Finish();
    key_images = teacher.map().nodes().size();
  }
  state.counters["frames_per_second"] =
      benchmark::Counter(static_cast<double>(kitti.frames.size()), benchmark::Counter::kIsIterationInvariantRate);
  state.counters["key_images"] = static_cast<double>(key_images);
  state.SetLabel(std::to_string(kitti.camera->width()) + "x" + std::to_string(kitti.camera->height()));
}
BENCHMARK(BM_TeachKitti)
    ->ArgsProduct({{0, 320}, {1, 0}})
    ->ArgNames({"width", "tests"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
}  // namespace retrace
