// Repeat throughput (single thread) on kitti07 — map taught from the even frames, the odd frames localized one by one,
// at native 1226x370 and at 320 px width (320x97) — and on the simulated town at the paper's 320x240 (teach drive /
// repeat variant with other sun, 1 m offset and pedestrians). The bootstrap frame is excluded from the timing;
// everything else a live run does per frame (pyramid, tracking, two current geometries, transfer, resumption,
// transitions, steering, and relocalization by wide-baseline matching when lost) is timed. `tracking_fraction` tells
// how many frames were localized: a fast run that is mostly lost is no achievement.
//
//
// BM_FindStart*: the latency of the first frame without a start arc (retrieval over every key-image + wide-baseline
// verification, features located; the localizer is built before the timing, as a robot builds it once when it loads
// the map), with a verification budget of 5 and 20 (the first argument, LocalizerOptions::start_retrieval_shortlist,
// whose default is 20; on kitti07 the first candidate verified is confident, so both stop there) and verifying every
// key-image (0); the second argument: 1 ranks by appearance and visual words fused (the default), 0 by appearance
// alone (LocalizerOptions::visual_word_retrieval). The map's visual words are built once, outside the timing.
// BM_BuildLocalizer*: building that localizer from the loaded map (timed with the first frame until 2026-12-07).
// BM_ExtractKeyImage*: what retrieval pays once for each key-image it verifies (wide-baseline key-points and
// descriptors of one key-image, cached by the localizer afterwards).
//
//   build/src/retrace/repeat/bench_repeat_repeat --benchmark_repetitions=5 --benchmark_report_aggregates_only=true

#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>

#include "retrace/camera/camera_io.h"
#include "retrace/dataset/sequence.h"
#include "retrace/feature/wide_baseline.h"
#include "retrace/image/image_utils.h"
#include "retrace/repeat/localizer.h"
#include "retrace/sim/recording.h"
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
  // As LoadMapForLocalizer: the visual words built once, shared by every Localizer given a copy of the map.
  setup->map.SetVisualWords(Localizer::BuildMapVisualWords(setup->map, LocalizerOptions()));
  SubsampledSequence odd(OpenSequence(kitti), 2, 1);
  while (auto frame = odd.Next()) {
    resize(&*frame);
    setup->repeat_frames.push_back(*frame);
  }
  entry = std::move(setup);
  return entry.get();
}

// The default simulated town drive (200 frames at 320x240) and its repeat variant; cached.
const Setup* GetSimSetup() {
  static std::unique_ptr<Setup> cached;
  if (cached) return cached.get();
  Scenario scenario;
  scenario.num_frames = 200;
  auto setup = std::make_unique<Setup>();
  RecordedDrive teach = RecordDrive(ApplyVariant(scenario, ScenarioVariant::kTeach));
  setup->camera = std::move(teach.camera);
  Teacher teacher(*setup->camera, TeachOptions(), nullptr);
  for (const Frame& frame : teach.frames) teacher.AddFrame(frame);
  teacher.Finish();
  setup->map = teacher.map();
  // As LoadMapForLocalizer: the visual words built once, shared by every Localizer given a copy of the map.
  setup->map.SetVisualWords(Localizer::BuildMapVisualWords(setup->map, LocalizerOptions()));
  setup->repeat_frames = RecordDrive(ApplyVariant(scenario, ScenarioVariant::kRepeat)).frames;
  cached = std::move(setup);
  return cached.get();
}

// GetSetup(width), or nullptr with the benchmark skipped when the shared data has no kitti07.
const Setup* KittiSetupOrSkip(int width, benchmark::State& state) {
  const Setup* setup = GetSetup(width);
  if (setup == nullptr) state.SkipWithError("kitti07 not found");
  return setup;
}

void RunRepeat(const Setup& setup, benchmark::State& state, const LocalizerOptions& options = LocalizerOptions()) {
  int64_t frames = 0, tracked = 0, tracking = 0;
  double tracking_seconds = 0.0;  // frames localized by tracking (no bootstrap / relocalization in them)
  for (auto _ : state) {
    state.PauseTiming();
    Localizer localizer(setup.map, *setup.camera, options);
    localizer.SetStartArc(setup.map.arcs().front().id);
    localizer.ProcessFrame(setup.repeat_frames.front());
    state.ResumeTiming();
    for (size_t i = 1; i < setup.repeat_frames.size(); ++i) {
      const FrameResult result = localizer.ProcessFrame(setup.repeat_frames[i]);
      tracked += result.tracked;
      if (result.state == LocalizerState::kTracking && !result.bootstrapped) {
        ++tracking;
        tracking_seconds += result.seconds;
      }
      ++frames;
    }
  }
  state.SetItemsProcessed(frames);
  state.counters["tracked_per_frame"] = frames > 0 ? static_cast<double>(tracked) / frames : 0.0;
  state.counters["tracking_fraction"] = frames > 0 ? static_cast<double>(tracking) / frames : 0.0;
  // Wall time of the frames localized by tracking alone, i.e. the steady-state cost without relocalizations.
  state.counters["ms_per_tracked_frame"] = tracking > 0 ? 1000.0 * tracking_seconds / tracking : 0.0;
  state.counters["width"] = setup.camera->width();
}

// kitti07 at the width of the benchmark's argument.
void RunRepeatKitti(benchmark::State& state, const LocalizerOptions& options = LocalizerOptions()) {
  const int width = static_cast<int>(state.range(0));
  if (const Setup* setup = KittiSetupOrSkip(width, state)) RunRepeat(*setup, state, options);
}

void BM_RepeatKitti(benchmark::State& state) { RunRepeatKitti(state); }
// 0 = native 1226x370; 320 = 320x97.
BENCHMARK(BM_RepeatKitti)->Arg(0)->Arg(320)->Unit(benchmark::kMillisecond)->Iterations(1);

void BM_RepeatSim(benchmark::State& state) { RunRepeat(*GetSimSetup(), state); }
BENCHMARK(BM_RepeatSim)->Unit(benchmark::kMillisecond)->Iterations(1);

// The same drives with other options, measured in the same process against the default: BM_RepeatKitti<name>/0,
// /320 and BM_RepeatSim<name> for each variant below.
void RegisterRepeatVariant(const std::string& name, LocalizerOptions options) {
  benchmark::RegisterBenchmark(("BM_RepeatKitti" + name).c_str(),
                               [options](benchmark::State& state) { RunRepeatKitti(state, options); })
      ->Arg(0)
      ->Arg(320)
      ->Unit(benchmark::kMillisecond)
      ->Iterations(1);
  benchmark::RegisterBenchmark(("BM_RepeatSim" + name).c_str(),
                               [options](benchmark::State& state) { RunRepeat(*GetSimSetup(), state, options); })
      ->Unit(benchmark::kMillisecond)
      ->Iterations(1);
}

const bool kVariantsRegistered = [] {
  // The tracker's affine fallback on (`repeat --affine`, LocalizerOptions::affine_fallback): what the fallback costs.
  LocalizerOptions affine;
  affine.affine_fallback = true;
  RegisterRepeatVariant("Affine", affine);
  // The three that are on by default off (LocalizerOptions::WithPaperWarp: the paper's warp alone; README, "The three
  // as the default"): what the default's affine refinement costs.
  RegisterRepeatVariant("Unrefined", LocalizerOptions().WithPaperWarp());
  // Each arc's points as its two key-images triangulated them (`repeat --no-multi-view-points`,
  // LocalizerOptions::multi_view_points off): what the default's points from more than two key-images cost.
  LocalizerOptions two_view_points;
  two_view_points.multi_view_points = false;
  RegisterRepeatVariant("TwoViewPoints", two_view_points);
  return true;
}();

// One frame localized from scratch (a fresh Localizer, no key-image features cached), `frame` of the repeat drive.
void RunFindStart(const Setup& setup, size_t frame, benchmark::State& state) {
  LocalizerOptions options;
  options.start_retrieval_shortlist = static_cast<int>(state.range(0));  // the budget of a first frame
  options.visual_word_retrieval = state.range(1) != 0;
  int64_t localized = 0, runs = 0;
  for (auto _ : state) {
    // Building the localizer (BM_BuildLocalizer*) is what a robot does once when it loads the map, not what its
    // first frame costs (as in `retrace bench kidnap`): outside the timing, and so is its destruction.
    state.PauseTiming();
    auto localizer = std::make_unique<Localizer>(setup.map, *setup.camera, options);
    state.ResumeTiming();
    localized += localizer->ProcessFrame(setup.repeat_frames.at(frame)).state == LocalizerState::kTracking;
    state.PauseTiming();
    localizer.reset();
    state.ResumeTiming();
    ++runs;
  }
  state.counters["localized_fraction"] = runs > 0 ? static_cast<double>(localized) / runs : 0.0;
  state.counters["key_images"] = static_cast<double>(setup.map.nodes().size());
}

// A localizer built from a loaded map: its per-key-image and per-arc tables, the appearance index and the arcs' points
// triangulated again from every key-image that sees them (LocalizerOptions::multi_view_points).
void RunBuildLocalizer(const Setup& setup, benchmark::State& state) {
  const LocalizerOptions options;
  for (auto _ : state) {
    auto localizer = std::make_unique<Localizer>(setup.map, *setup.camera, options);
    state.PauseTiming();
    localizer.reset();
    state.ResumeTiming();
  }
  state.counters["key_images"] = static_cast<double>(setup.map.nodes().size());
}

void BM_FindStartKitti(benchmark::State& state) {
  // Odd frame 81, the "start in the middle".
  if (const Setup* setup = KittiSetupOrSkip(0, state)) RunFindStart(*setup, 40, state);
}
BENCHMARK(BM_FindStartKitti)->Args({5, 1})->Args({20, 1})->Args({20, 0})->Args({0, 1})->Unit(benchmark::kMillisecond)->Iterations(1);

void BM_FindStartSim(benchmark::State& state) { RunFindStart(*GetSimSetup(), 100, state); }
BENCHMARK(BM_FindStartSim)->Args({5, 1})->Args({20, 1})->Args({20, 0})->Args({0, 1})->Unit(benchmark::kMillisecond)->Iterations(1);

void BM_BuildLocalizerKitti(benchmark::State& state) {
  if (const Setup* setup = KittiSetupOrSkip(0, state)) RunBuildLocalizer(*setup, state);
}
BENCHMARK(BM_BuildLocalizerKitti)->Unit(benchmark::kMillisecond);

void BM_BuildLocalizerSim(benchmark::State& state) { RunBuildLocalizer(*GetSimSetup(), state); }
BENCHMARK(BM_BuildLocalizerSim)->Unit(benchmark::kMillisecond);

void ExtractKeyImages(const Setup& setup, benchmark::State& state) {
  const WideBaselineOptions matching = LocalizerOptions().matching;
  size_t next = 0;
  for (auto _ : state) {
    const cv::Mat& image = setup.map.nodes()[next++ % setup.map.nodes().size()].image;
    benchmark::DoNotOptimize(ExtractWideBaselineFeatures(image, matching));
  }
  state.counters["width"] = setup.camera->width();
}

void BM_ExtractKeyImageKitti(benchmark::State& state) {
  if (const Setup* setup = KittiSetupOrSkip(0, state)) ExtractKeyImages(*setup, state);
}
BENCHMARK(BM_ExtractKeyImageKitti)->Unit(benchmark::kMillisecond);

void BM_ExtractKeyImageSim(benchmark::State& state) { ExtractKeyImages(*GetSimSetup(), state); }
BENCHMARK(BM_ExtractKeyImageSim)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace retrace
