#include "retrace/image/perturbation.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "retrace/image/image_utils.h"

namespace retrace {
namespace {

// SplitMix64 finaliser: turns (seed, stream, index) into well-mixed, reproducible RNG states.
uint64_t Mix(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

uint64_t StreamState(uint64_t seed, uint64_t stream, uint64_t index) {
  const uint64_t state = Mix(Mix(Mix(seed) ^ stream) ^ index);
  return state == 0 ? 1 : state;  // cv::RNG treats 0 specially
}

constexpr uint64_t kNoiseStream = 1;
constexpr uint64_t kOccluderStream = 2;

bool Fail(std::string* error, const std::string& message) {
  if (error != nullptr) *error = message;
  return false;
}

// Random grey blocks with darker edges, fixed to the occluder (same texture in every frame).
cv::Mat OccluderTexture(cv::Size size, uint64_t seed) {
  cv::RNG rng(StreamState(seed, kOccluderStream, 1));
  const int cell = std::max(4, std::min(size.width, size.height) / 6);
  cv::Mat texture(size, CV_8UC1);
  for (int y = 0; y < size.height; y += cell) {
    for (int x = 0; x < size.width; x += cell) {
      const cv::Rect block = cv::Rect(x, y, cell, cell) & cv::Rect(0, 0, size.width, size.height);
      texture(block).setTo(cv::Scalar(rng.uniform(30, 226)));
      cv::rectangle(texture, block, cv::Scalar(rng.uniform(0, 30)), 1);
    }
  }
  return texture;
}

}  // namespace

bool PerturbationOptions::Check(std::string* error) const {
  if (!(brightness >= 0) || !std::isfinite(brightness)) return Fail(error, "brightness must be >= 0");
  if (!(gamma > 0) || !std::isfinite(gamma)) return Fail(error, "gamma must be > 0");
  if (!(contrast >= 0) || !std::isfinite(contrast)) return Fail(error, "contrast must be >= 0");
  if (!(noise_sigma >= 0) || !std::isfinite(noise_sigma)) return Fail(error, "noise sigma must be >= 0");
  if (!(blur_sigma >= 0) || !std::isfinite(blur_sigma)) return Fail(error, "blur sigma must be >= 0");
  if (!(occluder_fraction >= 0 && occluder_fraction < 1)) return Fail(error, "occluder fraction must be in [0, 1)");
  if (occluder_gray < 0 || occluder_gray > 255) return Fail(error, "occluder grey level must be in 0..255");
  return true;
}

bool PerturbationOptions::IsIdentity() const {
  return brightness == 1.0 && gamma == 1.0 && contrast == 1.0 && noise_sigma == 0.0 && blur_sigma == 0.0 &&
         (occluder_fraction == 0.0 || occluder_last_frame < occluder_first_frame);
}

cv::Rect OccluderRect(cv::Size size, int64_t frame_index, const PerturbationOptions& options) {
  if (options.occluder_fraction <= 0 || frame_index < options.occluder_first_frame ||
      frame_index > options.occluder_last_frame || size.area() == 0) {
    return cv::Rect();
  }
  const double side = std::sqrt(options.occluder_fraction);
  const int width = std::clamp(static_cast<int>(std::lround(size.width * side)), 1, size.width);
  const int height = std::clamp(static_cast<int>(std::lround(size.height * side)), 1, size.height);
  const int64_t span = options.occluder_last_frame - options.occluder_first_frame;
  const double progress = span > 0 ? static_cast<double>(frame_index - options.occluder_first_frame) / span : 0.0;
  const int x = static_cast<int>(std::lround(progress * (size.width - width)));
  // Vertical position fixed for the whole pass, drawn from the seed.
  cv::RNG rng(StreamState(options.seed, kOccluderStream, 0));
  const int y = rng.uniform(0, size.height - height + 1);
  return cv::Rect(x, y, width, height);
}

cv::Mat PerturbImage(const cv::Mat& image, int64_t frame_index, const PerturbationOptions& options) {
  cv::Mat out = ToGray8(image);
  if (out.empty() || options.IsIdentity()) return out;

  // 1. Occluder (part of the scene, so it is lit, blurred and noisy like everything else).
  const cv::Rect occluder = OccluderRect(out.size(), frame_index, options);
  if (!occluder.empty()) {
    if (options.occluder_textured) {
      OccluderTexture(occluder.size(), options.seed).copyTo(out(occluder));
    } else {
      out(occluder).setTo(cv::Scalar(options.occluder_gray));
    }
  }

  // 2. Photometric change through a lookup table: v' = a v^g, v'' = 0.5 + c (v' - 0.5).
  if (options.brightness != 1.0 || options.gamma != 1.0 || options.contrast != 1.0) {
    cv::Mat lut(1, 256, CV_8UC1);
    for (int level = 0; level < 256; ++level) {
      const double v = options.brightness * std::pow(level / 255.0, options.gamma);
      const double w = 0.5 + options.contrast * (v - 0.5);
      lut.at<uint8_t>(level) = cv::saturate_cast<uint8_t>(std::lround(std::clamp(w, 0.0, 1.0) * 255.0));
    }
    cv::LUT(out, lut, out);
  }

  // 3. Blur.
  if (options.blur_sigma > 0) cv::GaussianBlur(out, out, cv::Size(0, 0), options.blur_sigma, options.blur_sigma,
                                               cv::BORDER_REFLECT_101);

  // 4. Sensor noise, a reproducible stream per (seed, frame).
  if (options.noise_sigma > 0) {
    cv::RNG rng(StreamState(options.seed, kNoiseStream, static_cast<uint64_t>(frame_index)));
    cv::Mat noise(out.size(), CV_32FC1);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, options.noise_sigma);
    cv::Mat noisy;
    out.convertTo(noisy, CV_32FC1);
    noisy += noise;
    noisy.convertTo(out, CV_8UC1);  // rounds and saturates
  }
  return out;
}

}  // namespace retrace
