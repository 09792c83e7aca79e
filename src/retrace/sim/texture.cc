#include "retrace/sim/texture.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

namespace retrace {

Texture::Texture(const cv::Mat& image) {
  cv::Mat rgb;
  if (image.type() == CV_8UC3) {
    cv::cvtColor(image, rgb, cv::COLOR_BGR2RGB);
    rgb.convertTo(rgb, CV_32FC3, 1.0 / 255.0);
  } else {
    CV_Assert(image.type() == CV_32FC3);
    rgb = image;
  }
  CV_Assert(rgb.cols >= 1 && rgb.rows >= 1);
  cv::Mat current = rgb;
  while (true) {
    Level level;
    level.width = current.cols;
    level.height = current.rows;
    level.texels.resize(static_cast<size_t>(level.width) * level.height);
    for (int y = 0; y < current.rows; ++y) {
      const cv::Vec3f* row = current.ptr<cv::Vec3f>(y);
      for (int x = 0; x < current.cols; ++x) {
        level.texels[static_cast<size_t>(y) * level.width + x] = Vector3f(row[x][0], row[x][1], row[x][2]);
      }
    }
    level.gray.resize(level.texels.size());
    for (size_t i = 0; i < level.texels.size(); ++i) {
      const float lum = 0.2126f * level.texels[i].x() + 0.7152f * level.texels[i].y() + 0.0722f * level.texels[i].z();
      level.gray[i] = static_cast<uint8_t>(std::min(255.0f, std::max(0.0f, std::round(255.0f * lum))));
    }
    levels_.push_back(std::move(level));
    if (current.cols == 1 && current.rows == 1) break;
    cv::Mat next;
    cv::resize(current, next, cv::Size(std::max(1, current.cols / 2), std::max(1, current.rows / 2)), 0, 0,
               cv::INTER_AREA);
    current = next;
  }
}

namespace {

// Bilinear lookup with wrap-around; texel centres at (i + 0.5) / width (no integer division on the hot path).
// Fractional part in [0, 1) without std::floor (a library call on baseline x86-64); |x| < 2^31.
inline float Fraction(float x) {
  const float f = x - static_cast<float>(static_cast<int>(x));
  return f < 0.0f ? f + 1.0f : f;
}

// Texel value as the sampled type: colours as they are, grey bytes scaled back to [0, 1].
inline const Vector3f& Value(const Vector3f& texel) { return texel; }
inline float Value(uint8_t texel) { return texel * (1.0f / 255.0f); }

#if defined(__GNUC__)
#define RETRACE_ALWAYS_INLINE __attribute__((always_inline)) inline
#else
#define RETRACE_ALWAYS_INLINE inline
#endif

template <typename T, typename S>
RETRACE_ALWAYS_INLINE T Bilinear(const std::vector<S>& texels, int width, int height, float u, float v) {
  if (!(std::abs(u) < 1e9f) || !(std::abs(v) < 1e9f)) return Value(texels[0]);
  const float x = Fraction(u) * width - 0.5f + 1.0f;  // in [0.5, width + 0.5): truncation = floor
  const float y = Fraction(v) * height - 0.5f + 1.0f;
  const int xi = static_cast<int>(x);
  const int yi = static_cast<int>(y);
  const float ax = x - xi;
  const float ay = y - yi;
  int x0 = xi - 1, y0 = yi - 1;
  if (x0 < 0) x0 += width;
  if (y0 < 0) y0 += height;
  if (x0 >= width) x0 -= width;
  if (y0 >= height) y0 -= height;
  const int x1 = x0 + 1 == width ? 0 : x0 + 1;
  const int y1 = y0 + 1 == height ? 0 : y0 + 1;
  const S* r0 = texels.data() + static_cast<size_t>(y0) * width;
  const S* r1 = texels.data() + static_cast<size_t>(y1) * width;
  return (1.0f - ay) * ((1.0f - ax) * Value(r0[x0]) + ax * Value(r0[x1])) +
         ay * ((1.0f - ax) * Value(r1[x0]) + ax * Value(r1[x1]));
}

}  // namespace

template <typename T, typename S>
T Texture::Trilinear(const std::vector<S> Level::*channel, float u, float v, float level) const {
  if (!std::isfinite(u) || !std::isfinite(v)) level = 1e9f;
  const int last = num_levels() - 1;
  if (level <= 0.0f) return Bilinear<T>(levels_[0].*channel, levels_[0].width, levels_[0].height, u, v);
  if (level >= last) return Value((levels_[last].*channel)[0]);
  const int l0 = static_cast<int>(level);
  const float a = level - l0;
  const Level& a_level = levels_[l0];
  const T c0 = Bilinear<T>(a_level.*channel, a_level.width, a_level.height, u, v);
  if (a < 1e-3f) return c0;
  const Level& b_level = levels_[l0 + 1];
  return (1.0f - a) * c0 + a * Bilinear<T>(b_level.*channel, b_level.width, b_level.height, u, v);
}

template <typename T, typename S>
T Texture::Filtered(const std::vector<S> Level::*channel, float u, float v, const Vector2f& axis_a,
                    const Vector2f& axis_b) const {
  const float w = static_cast<float>(width());
  const float h = static_cast<float>(height());
  // Footprint axes in texels of level 0.
  const float la = std::sqrt(axis_a.x() * axis_a.x() * w * w + axis_a.y() * axis_a.y() * h * h);
  const float lb = std::sqrt(axis_b.x() * axis_b.x() * w * w + axis_b.y() * axis_b.y() * h * h);
  const Vector2f& major_axis = la >= lb ? axis_a : axis_b;
  const float major = std::max(la, lb);
  const float minor = std::max(std::min(la, lb), 1e-6f);
  if (major <= 1.0f) return Trilinear<T>(channel, u, v, 0.0f);
  const int taps = std::min(kMaxAnisotropy, static_cast<int>(std::ceil(major / minor)));
  // The level of detail covers what the taps do not: the footprint length per tap.
  const float level = std::log2(std::max(1.0f, major / taps));
  if (taps <= 1) return Trilinear<T>(channel, u, v, level);
  T sum = Trilinear<T>(channel, u + (0.5f / taps - 0.5f) * major_axis.x(), v + (0.5f / taps - 0.5f) * major_axis.y(),
                    level);
  for (int i = 1; i < taps; ++i) {
    const float s = (i + 0.5f) / taps - 0.5f;
    sum += Trilinear<T>(channel, u + s * major_axis.x(), v + s * major_axis.y(), level);
  }
  return sum * (1.0f / taps);
}

Vector3f Texture::SampleTrilinear(float u, float v, float level) const {
  return Trilinear<Vector3f>(&Level::texels, u, v, level);
}

Vector3f Texture::SampleFiltered(float u, float v, const Vector2f& axis_a, const Vector2f& axis_b) const {
  return Filtered<Vector3f>(&Level::texels, u, v, axis_a, axis_b);
}

float Texture::SampleTrilinearGray(float u, float v, float level) const {
  return Trilinear<float>(&Level::gray, u, v, level);
}

float Texture::SampleFilteredGray(float u, float v, const Vector2f& axis_a, const Vector2f& axis_b) const {
  return Filtered<float>(&Level::gray, u, v, axis_a, axis_b);
}

Vector3f Texture::Mean() const { return levels_.empty() ? Vector3f(0.5f, 0.5f, 0.5f) : levels_.back().texels[0]; }

}  // namespace retrace
