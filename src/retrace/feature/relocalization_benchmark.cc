// What a relocalizing frame pays in the feature layer (issue 16), 1 thread:
//  - BM_ExtractBinary: upright ORB key-points and descriptors of one image (binary_features.h), 320x240 and
//    1226x370, against BM_ExtractWideBaseline (SIFT from three detectors, wide_baseline.h) on the same images;
//  - BM_DescribeBinaryKeyPoints: the same descriptors of given key-points (reading a key-image's stored differences);
//  - BM_MatchBinary: the Hamming table, ratio test and cross-check of two 320x240 images;
//  - BM_HammingNearest/K: the scan of all pairs alone (hamming_nearest.h) for a relocalizing frame's 822 random
//    descriptors against a key-image's 850, kernel K = 1 portable, 2 POPCNT, 3 AVX2, 4 AVX-512 (skipped where the
//    CPU lacks it);
//  - BM_AppearanceIndexRank/N: ranking N key-images by their quantised thumbnails (global_descriptor.h);
//  - BM_VisualWordsQuantize: the words of a 320x240 frame's ORB descriptors in a vocabulary of about 10^4 words;
//  - BM_VisualWordIndexRank/N: ranking N key-images of 1000 words each by tf-idf through the inverted file
//    (visual_words.h).
//
//   build/src/retrace/feature/bench_feature_relocalization --benchmark_repetitions=5
//     --benchmark_report_aggregates_only=true

#include <numeric>
#include <random>

#include <benchmark/benchmark.h>
#include <opencv2/imgproc.hpp>

#include "retrace/feature/binary_features.h"
#include "retrace/feature/global_descriptor.h"
#include "retrace/feature/hamming_nearest.h"
#include "retrace/feature/synthetic_texture.h"
#include "retrace/feature/visual_words.h"

namespace retrace {
namespace {

cv::Mat Texture(int width, int height, uint64_t seed) {
  SyntheticTextureOptions options;
  options.width = width;
  options.height = height;
  options.num_shapes = std::max(4, width * height / 500);
  options.seed = seed;
  cv::Mat image;
  SyntheticTexture(options).Render(width, height).convertTo(image, CV_8U);
  return image;
}

void BM_ExtractBinary(benchmark::State& state) {
  const cv::Mat image = Texture(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)), 1);
  size_t keypoints = 0;
  for (auto _ : state) keypoints = ExtractBinaryFeatures(image).size();
  state.counters["keypoints"] = static_cast<double>(keypoints);
}
BENCHMARK(BM_ExtractBinary)->Args({320, 240})->Args({1226, 370})->Unit(benchmark::kMillisecond);

// Describing a stored key-image again at its 1000 stored key-points: what reading back descriptors stored as
// differences costs (map/descriptor_coding.h), besides decoding the key-image.
void BM_DescribeBinaryKeyPoints(benchmark::State& state) {
  const cv::Mat image = Texture(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)), 1);
  const std::vector<cv::KeyPoint> keypoints = ExtractBinaryFeatures(image).keypoints;
  int rows = 0;
  for (auto _ : state) rows = DescribeBinaryKeyPoints(image, keypoints).rows;
  state.counters["keypoints"] = rows;
}
BENCHMARK(BM_DescribeBinaryKeyPoints)->Args({320, 240})->Args({1226, 370})->Unit(benchmark::kMillisecond);

void BM_ExtractWideBaseline(benchmark::State& state) {
  const cv::Mat image = Texture(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)), 1);
  size_t keypoints = 0;
  for (auto _ : state) keypoints = ExtractWideBaselineFeatures(image).size();
  state.counters["keypoints"] = static_cast<double>(keypoints);
}
BENCHMARK(BM_ExtractWideBaseline)->Args({320, 240})->Args({1226, 370})->Unit(benchmark::kMillisecond);

void BM_MatchBinary(benchmark::State& state) {
  const cv::Mat a = Texture(320, 240, 2);
  cv::Mat transform = cv::getRotationMatrix2D(cv::Point2f(160, 120), 0.0, 1.1), b;
  cv::warpAffine(a, b, transform, a.size());
  const WideBaselineFeatures fa = ExtractBinaryFeatures(a), fb = ExtractBinaryFeatures(b);
  size_t matches = 0;
  for (auto _ : state) matches = MatchBinary(fa, fb).size();
  state.counters["keypoints"] = static_cast<double>(fa.size());
  state.counters["matches"] = static_cast<double>(matches);
}
BENCHMARK(BM_MatchBinary)->Unit(benchmark::kMillisecond);

void BM_HammingNearest(benchmark::State& state) {
  const auto kernel = static_cast<HammingKernel>(state.range(0));
  if (!HammingKernelAvailable(kernel)) {
    state.SkipWithError("kernel not available on this CPU");
    return;
  }
  cv::Mat query(822, 32, CV_8U), train(850, 32, CV_8U);
  cv::RNG rng(5);
  rng.fill(query, cv::RNG::UNIFORM, 0, 256);
  rng.fill(train, cv::RNG::UNIFORM, 0, 256);
  int nearest_of_first = 0;
  for (auto _ : state) nearest_of_first = FindHammingNearest(query, train, kernel).best[0];
  benchmark::DoNotOptimize(nearest_of_first);
}
BENCHMARK(BM_HammingNearest)
    ->Arg(static_cast<int>(HammingKernel::kPortable))
    ->Arg(static_cast<int>(HammingKernel::kPopcnt))
    ->Arg(static_cast<int>(HammingKernel::kAvx2))
    ->Arg(static_cast<int>(HammingKernel::kAvx512))
    ->Unit(benchmark::kMillisecond);

void BM_AppearanceIndexRank(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  AppearanceIndex index;
  // Distinct thumbnails without rendering n images: random patch-normalised-like values.
  cv::RNG rng(3);
  for (int i = 0; i < n; ++i) {
    cv::Mat thumbnail(36, 48, CV_32F);
    rng.fill(thumbnail, cv::RNG::NORMAL, 0.0, 1.0);
    index.Add(QuantizeGlobalDescriptor(GlobalDescriptor{thumbnail}));
  }
  const cv::Mat query = QuantizeGlobalDescriptor(ComputeGlobalDescriptor(Texture(320, 240, 4)));
  std::vector<size_t> all(n);
  std::iota(all.begin(), all.end(), 0);
  for (auto _ : state) benchmark::DoNotOptimize(index.Rank(query, all));
  state.counters["key_images"] = n;
}
BENCHMARK(BM_AppearanceIndexRank)->Arg(1000)->Arg(4000)->Unit(benchmark::kMillisecond);

// A vocabulary trained on the ORB descriptors of 200 textured images (200 000 descriptors at most, as a map's), the
// frame one more image.
void BM_VisualWordsQuantize(benchmark::State& state) {
  std::vector<cv::Mat> descriptors;
  for (int i = 0; i < 200; ++i) descriptors.push_back(ExtractBinaryFeatures(Texture(320, 240, 100 + i)).descriptors);
  const VisualWords words = BuildVisualWords(descriptors);
  const cv::Mat frame = ExtractBinaryFeatures(Texture(320, 240, 7)).descriptors;
  for (auto _ : state) benchmark::DoNotOptimize(words.vocabulary.Words(frame));
  state.counters["words"] = words.vocabulary.size();
  state.counters["descriptors"] = frame.rows;
}
BENCHMARK(BM_VisualWordsQuantize)->Unit(benchmark::kMillisecond);

void BM_VisualWordIndexRank(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  constexpr int kWords = 10000, kPerImage = 1000;
  // Word frequencies as in a natural vocabulary (Zipf: the r-th most common word r times rarer than the first).
  std::mt19937_64 rng(5);
  std::vector<double> zipf(kWords);
  for (int w = 0; w < kWords; ++w) zipf[w] = 1.0 / (w + 1);
  std::discrete_distribution<int> word(zipf.begin(), zipf.end());
  const auto image = [&] {
    std::vector<int> words(kPerImage);
    for (int& w : words) w = word(rng);
    return words;
  };
  VisualWordIndex index(kWords);
  for (int i = 0; i < n; ++i) index.Add(image());
  index.ShrinkToFit();
  const std::vector<int> query = image();
  std::vector<size_t> all(n);
  std::iota(all.begin(), all.end(), 0);
  benchmark::DoNotOptimize(index.Rank(query, all));  // the idf weights, computed once
  for (auto _ : state) benchmark::DoNotOptimize(index.Rank(query, all));
  state.counters["key_images"] = n;
}
BENCHMARK(BM_VisualWordIndexRank)->Arg(1000)->Arg(4000)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace retrace
