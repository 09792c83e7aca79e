// Speed of the reference-aligned tracker: 150 features per 320x240 frame, single thread, including the
// per-frame image preparation (float conversion, pre-smoothing, 3-level pyramid).
//
//   build/src/retrace/feature/bench_feature_tracker --benchmark_repetitions=5
//   --benchmark_report_aggregates_only=true

#include <benchmark/benchmark.h>

#include <cmath>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "retrace/feature/corner_detector.h"
#include "retrace/feature/feature_tracker.h"
#include "retrace/feature/synthetic_texture.h"

namespace retrace {
namespace {

constexpr int kWidth = 320;
constexpr int kHeight = 240;
constexpr int kNumFeatures = 150;

// A periodic camera motion over the generated texture: translation on a circle of radius 25 px (about 2.5 px
// per frame) and a zoom oscillating by +-8 %, so that the sequence can be looped.
std::vector<cv::Mat> SyntheticSequence(int num_frames) {
  SyntheticTextureOptions options;
  options.width = 640;
  options.height = 480;
  options.num_shapes = 1200;
  const SyntheticTexture texture(options);
  std::vector<cv::Mat> frames;
  for (int i = 0; i < num_frames; ++i) {
    const double phase = 2.0 * M_PI * i / num_frames;
    const double scale = 1.0 + 0.08 * std::sin(2.0 * phase);
    // Keep the texture centre (320, 240) near the image centre (160, 120).
    const Vector2d translation = Vector2d(160.0, 120.0) - scale * Vector2d(320.0, 240.0) +
                                 25.0 * Vector2d(std::cos(phase), std::sin(phase));
    cv::Mat frame;
    texture.Render(kWidth, kHeight, scale, translation).convertTo(frame, CV_8U);
    frames.push_back(frame);
  }
  return frames;
}

// KITTI 07 frames: the central 493x370 (4:3) part resized to 320x240.
std::vector<cv::Mat> KittiSequence(int num_frames) {
  const std::filesystem::path dir = std::filesystem::path(RETRACE_SHARED_DATA_DIR) / "kitti07" / "image_0";
  const char* env = std::getenv("RETRACE_DATA");
  const std::filesystem::path folder = env ? std::filesystem::path(env) / "kitti07" / "image_0" : dir;
  std::vector<cv::Mat> frames;
  for (int i = 0; i < num_frames; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.png", i);
    const cv::Mat image = cv::imread((folder / name).string(), cv::IMREAD_GRAYSCALE);
    if (image.empty()) return {};
    const int crop_width = image.rows * 4 / 3;
    cv::Mat frame;
    cv::resize(image(cv::Rect((image.cols - crop_width) / 2, 0, crop_width, image.rows)), frame,
               cv::Size(kWidth, kHeight), 0, 0, cv::INTER_AREA);
    frames.push_back(frame);
  }
  return frames;
}

void TrackSequence(benchmark::State& state, const std::vector<cv::Mat>& frames) {
  if (frames.empty()) {
    state.SkipWithError("sequence not available");
    return;
  }
  cv::setNumThreads(1);
  CornerDetectorOptions detector;
  detector.max_corners = kNumFeatures;
  detector.min_distance = 8.0;
  FeatureTracker tracker;
  ImagePyramid pyramid;
  size_t frame_index = 0;
  int64_t tracked = 0, attempted = 0, frames_done = 0, refills = 0;
  std::vector<Vector2d> existing;
  for (auto _ : state) {
    pyramid.Build(frames[frame_index]);
    const std::vector<TrackedFeature>& results = tracker.Track(pyramid);
    benchmark::DoNotOptimize(results.data());
    attempted += static_cast<int64_t>(results.size());
    tracked += tracker.NumFeatures();
    ++frames_done;
    frame_index = (frame_index + 1) % frames.size();
    if (tracker.NumFeatures() < kNumFeatures) {
      // Keep 150 features: detection is not part of the measured tracking time.
      state.PauseTiming();
      existing.clear();
      for (const TrackedFeature& f : tracker.Features()) existing.push_back(f.warp.position);
      detector.max_corners = kNumFeatures - tracker.NumFeatures();
      std::vector<Vector2d> positions;
      for (const Corner& c : DetectCorners(pyramid, detector, cv::Mat(), existing))
        positions.push_back(c.position);
      tracker.AddFeatures(pyramid, positions);
      ++refills;
      state.ResumeTiming();
    }
  }
  state.counters["features_per_frame"] =
      benchmark::Counter(static_cast<double>(tracked) / std::max<int64_t>(1, frames_done));
  state.counters["attempted_per_frame"] =
      benchmark::Counter(static_cast<double>(attempted) / std::max<int64_t>(1, frames_done));
  state.counters["refills_per_frame"] =
      benchmark::Counter(static_cast<double>(refills) / std::max<int64_t>(1, frames_done));
  state.counters["fps"] = benchmark::Counter(static_cast<double>(frames_done), benchmark::Counter::kIsRate);
}

void BM_TrackSynthetic320x240(benchmark::State& state) {
  static const std::vector<cv::Mat> frames = SyntheticSequence(100);
  TrackSequence(state, frames);
}
BENCHMARK(BM_TrackSynthetic320x240)->Unit(benchmark::kMicrosecond);

void BM_TrackKitti320x240(benchmark::State& state) {
  static const std::vector<cv::Mat> frames = KittiSequence(100);
  TrackSequence(state, frames);
}
BENCHMARK(BM_TrackKitti320x240)->Unit(benchmark::kMicrosecond);

void BM_BuildPyramid320x240(benchmark::State& state) {
  static const std::vector<cv::Mat> frames = SyntheticSequence(4);
  cv::setNumThreads(1);
  ImagePyramid pyramid;
  size_t i = 0;
  for (auto _ : state) {
    pyramid.Build(frames[i++ % frames.size()]);
    benchmark::DoNotOptimize(pyramid.Level(0).data);
  }
}
BENCHMARK(BM_BuildPyramid320x240)->Unit(benchmark::kMicrosecond);

// The pyramid teach and repeat build for each frame and each key-image whose references are cut
// (TrackingPyramidOptions: the pre-smoothing and the levels scaled with the width; 7 taps at 320 px, 19 at 1226 px),
// from an 8-bit image.
void BM_BuildTrackingPyramid(benchmark::State& state) {
  const cv::Size size(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  cv::Mat image;
  cv::resize(SyntheticSequence(1).front(), image, size, 0.0, 0.0, cv::INTER_LINEAR);
  cv::setNumThreads(1);
  ImagePyramid pyramid;
  const ImagePyramidOptions options = TrackingPyramidOptions(size.width);
  for (auto _ : state) {
    pyramid.Build(image, options);
    benchmark::DoNotOptimize(pyramid.Level(0).data);
  }
  state.counters["levels"] = options.num_levels;
}
BENCHMARK(BM_BuildTrackingPyramid)->Args({320, 240})->Args({1226, 370})->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace retrace
