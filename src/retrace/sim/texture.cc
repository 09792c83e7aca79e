#include "retrace/sim/texture.h"

#include <algorithm>
#include <cmath>
#include <cstring>

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
    level.stride = level.width + 1;
    // One extra column and row repeat the first ones: a bilinear lookup never wraps inside its 2x2 texels.
    const size_t padded = static_cast<size_t>(level.stride) * (level.height + 1);
    level.texels.resize(padded);
    level.gray.resize(padded);
    for (int y = 0; y <= level.height; ++y) {
      const cv::Vec3f* row = current.ptr<cv::Vec3f>(y % level.height);
      for (int x = 0; x <= level.width; ++x) {
        const cv::Vec3f& c = row[x % level.width];
        const size_t i = static_cast<size_t>(y) * level.stride + x;
        level.texels[i] = Vector3f(c[0], c[1], c[2]);
        const float lum = 0.2126f * c[0] + 0.7152f * c[1] + 0.0722f * c[2];
        level.gray[i] = static_cast<uint8_t>(std::min(255.0f, std::max(0.0f, std::round(255.0f * lum))));
      }
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

#if defined(__GNUC__)
#define RETRACE_ALWAYS_INLINE __attribute__((always_inline)) inline
#else
#define RETRACE_ALWAYS_INLINE inline
#endif

// Fractional part in [0, 1] without std::floor (a library call on baseline x86-64); |x| < 2^31. (It can round to
// exactly 1 for tiny negative x, which the padded levels handle like 0.)
RETRACE_ALWAYS_INLINE float Fraction(float x) {
  const float f = x - static_cast<float>(static_cast<int>(x));
  return f < 0.0f ? f + 1.0f : f;
}

// log2(x) for x > 0 (normal floats) from the exponent bits and a quadratic in the mantissa m in [1, 2):
// log2(m) ~ t (a + (1 - a) t), t = m - 1, exact at both ends (so continuous across octaves), error < 0.005. Used
// for the level of detail, where that error is invisible.
RETRACE_ALWAYS_INLINE float FastLog2(float x) {
  uint32_t bits;
  std::memcpy(&bits, &x, sizeof(bits));
  const int exponent = static_cast<int>((bits >> 23) & 0xff) - 127;
  bits = (bits & 0x007fffffu) | 0x3f800000u;
  float m;
  std::memcpy(&m, &bits, sizeof(m));
  const float t = m - 1.0f;
  return static_cast<float>(exponent) + t * (1.3466f - 0.3466f * t);
}

// Texel value as the sampled type: colours as they are, grey bytes scaled back to [0, 1] (by the caller).
RETRACE_ALWAYS_INLINE const Vector3f& Value(const Vector3f& texel) { return texel; }
RETRACE_ALWAYS_INLINE float Value(uint8_t texel) { return static_cast<float>(texel); }
template <typename T>
RETRACE_ALWAYS_INLINE T Zero() {
  return T(0.0f);
}
template <>
RETRACE_ALWAYS_INLINE Vector3f Zero<Vector3f>() {
  return Vector3f::Zero();
}
template <typename S>
constexpr float kValueScale = 1.0f;
template <>
constexpr float kValueScale<uint8_t> = 1.0f / 255.0f;

// Bilinear lookup at the fractional texture coordinates (fu, fv) in [0, 1) on a padded level; texel centres at
// (i + 0.5) / width.
template <typename T, typename S>
RETRACE_ALWAYS_INLINE T Bilinear(const S* texels, int width, int height, int stride, float fu, float fv) {
  float x = fu * width - 0.5f;
  float y = fv * height - 0.5f;
  if (x < 0.0f) x += width;  // the left half of texel 0 blends with the last texel: wrap around
  if (y < 0.0f) y += height;
  const int xi = std::min(static_cast<int>(x), width - 1);
  const int yi = std::min(static_cast<int>(y), height - 1);
  const float ax = x - xi;
  const float ay = y - yi;
  const S* p = texels + static_cast<size_t>(yi) * stride + xi;
  const T top = Value(p[0]) + ax * (Value(p[1]) - Value(p[0]));
  const T bottom = Value(p[stride]) + ax * (Value(p[stride + 1]) - Value(p[stride]));
  return top + ay * (bottom - top);
}

}  // namespace

template <typename T, typename S>
T Texture::Taps(const std::vector<S> Level::*channel, float u, float v, float du, float dv, int taps,
                float level) const {
  const int last = num_levels() - 1;
  if (!(std::abs(u) < 1e9f) || !(std::abs(v) < 1e9f) || !(level < last)) {
    return Value((levels_[last].*channel)[0]) * kValueScale<S>;
  }
  level = std::max(0.0f, level);
  const int l0 = static_cast<int>(level);
  // Blend weight of the coarser level: linear in the middle half of the octave only, one level alone in the outer
  // quarters ("brilinear", as GPU drivers do): still continuous in the level of detail, so nothing pops as the
  // camera moves, and half of the lookups read a single level.
  const float a = std::min(1.0f, std::max(0.0f, 2.0f * (level - l0) - 0.5f));
  // Taps at (u, v) + s (du, dv), s = (i + 0.5) / taps - 0.5.
  const float step = 1.0f / taps;
  float s = 0.5f * step - 0.5f;
  T sum_a = Zero<T>(), sum_b = Zero<T>();
  if (a <= 0.0f || a >= 1.0f) {
    const Level& l = levels_[a <= 0.0f ? l0 : l0 + 1];
    const S* t = (l.*channel).data();
    for (int i = 0; i < taps; ++i, s += step) {
      sum_a += Bilinear<T>(t, l.width, l.height, l.stride, Fraction(u + s * du), Fraction(v + s * dv));
    }
    return sum_a * (step * kValueScale<S>);
  }
  const Level& la = levels_[l0];
  const Level& lb = levels_[l0 + 1];
  const S* ta = (la.*channel).data();
  const S* tb = (lb.*channel).data();
  for (int i = 0; i < taps; ++i, s += step) {
    const float fu = Fraction(u + s * du), fv = Fraction(v + s * dv);
    sum_a += Bilinear<T>(ta, la.width, la.height, la.stride, fu, fv);
    sum_b += Bilinear<T>(tb, lb.width, lb.height, lb.stride, fu, fv);
  }
  return (sum_a + a * (sum_b - sum_a)) * (step * kValueScale<S>);
}

template <typename T, typename S>
T Texture::Filtered(const std::vector<S> Level::*channel, float u, float v, const Vector2f& axis_a,
                    const Vector2f& axis_b) const {
  const float w = static_cast<float>(width());
  const float h = static_cast<float>(height());
  // Squared footprint axes in texels of level 0.
  const float la2 = axis_a.x() * axis_a.x() * w * w + axis_a.y() * axis_a.y() * h * h;
  const float lb2 = axis_b.x() * axis_b.x() * w * w + axis_b.y() * axis_b.y() * h * h;
  const Vector2f& major_axis = la2 >= lb2 ? axis_a : axis_b;
  const float major2 = std::max(la2, lb2);
  const float minor2 = std::max(std::min(la2, lb2), 1e-12f);
  if (!(major2 > 1.0f)) return Taps<T>(channel, u, v, 0.0f, 0.0f, 1, 0.0f);
  // taps = ceil(major / minor), at most kMaxAnisotropy, compared on squares.
  const float ratio2 = major2 / minor2;
  int taps = 1;
  while (taps < kMaxAnisotropy && ratio2 > static_cast<float>(taps * taps)) ++taps;
  // The level of detail covers what the taps do not: the footprint length per tap, log2(major / taps).
  const float level = 0.5f * FastLog2(major2 / static_cast<float>(taps * taps));
  return Taps<T>(channel, u, v, major_axis.x(), major_axis.y(), taps, level);
}

Vector3f Texture::SampleTrilinear(float u, float v, float level) const {
  return Taps<Vector3f>(&Level::texels, u, v, 0.0f, 0.0f, 1, level);
}

Vector3f Texture::SampleFiltered(float u, float v, const Vector2f& axis_a, const Vector2f& axis_b) const {
  return Filtered<Vector3f>(&Level::texels, u, v, axis_a, axis_b);
}

float Texture::SampleTrilinearGray(float u, float v, float level) const {
  return Taps<float>(&Level::gray, u, v, 0.0f, 0.0f, 1, level);
}

float Texture::SampleFilteredGray(float u, float v, const Vector2f& axis_a, const Vector2f& axis_b) const {
  return Filtered<float>(&Level::gray, u, v, axis_a, axis_b);
}

Vector3f Texture::Mean() const { return levels_.empty() ? Vector3f(0.5f, 0.5f, 0.5f) : levels_.back().texels[0]; }

}  // namespace retrace
