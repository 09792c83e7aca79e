// Speed of PerturbImage on a KITTI-sized frame (1226x370), per perturbation kind.

#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>

#include "retrace/image/perturbation.h"

namespace retrace {
namespace {

cv::Mat KittiSizedImage() {
  cv::Mat image(370, 1226, CV_8UC1);
  cv::RNG rng(1);
  rng.fill(image, cv::RNG::UNIFORM, 0, 256);
  return image;
}

void Run(benchmark::State& state, const PerturbationOptions& options) {
  const cv::Mat image = KittiSizedImage();
  int64_t frame = 0;
  for (auto _ : state) {
    cv::Mat out = PerturbImage(image, frame++ % 100, options);
    benchmark::DoNotOptimize(out.data);
  }
  state.SetItemsProcessed(state.iterations());
}

void BM_PerturbPhotometric(benchmark::State& state) {
  PerturbationOptions options;
  options.brightness = 0.6;
  options.gamma = 1.4;
  options.contrast = 0.8;
  Run(state, options);
}
BENCHMARK(BM_PerturbPhotometric);

void BM_PerturbNoise(benchmark::State& state) {
  PerturbationOptions options;
  options.noise_sigma = 6;
  Run(state, options);
}
BENCHMARK(BM_PerturbNoise);

void BM_PerturbBlur(benchmark::State& state) {
  PerturbationOptions options;
  options.blur_sigma = 2;
  Run(state, options);
}
BENCHMARK(BM_PerturbBlur);

void BM_PerturbAll(benchmark::State& state) {
  PerturbationOptions options;
  options.brightness = 0.6;
  options.gamma = 1.4;
  options.noise_sigma = 6;
  options.blur_sigma = 1;
  options.occluder_fraction = 0.4;
  options.occluder_first_frame = 0;
  options.occluder_last_frame = 99;
  Run(state, options);
}
BENCHMARK(BM_PerturbAll);

}  // namespace
}  // namespace retrace
