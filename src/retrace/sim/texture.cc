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
    levels_.push_back(std::move(level));
    if (current.cols == 1 && current.rows == 1) break;
    cv::Mat next;
    cv::resize(current, next, cv::Size(std::max(1, current.cols / 2), std::max(1, current.rows / 2)), 0, 0,
               cv::INTER_AREA);
    current = next;
  }
}

Vector3f Texture::SampleBilinear(const Level& level, float u, float v) const {
  // Texel centres at (i + 0.5) / width; the texture repeats (wrap by the fractional part, no integer division).
  const float x = (u - std::floor(u)) * level.width - 0.5f;
  const float y = (v - std::floor(v)) * level.height - 0.5f;
  const float fx = std::floor(x);
  const float fy = std::floor(y);
  const float ax = x - fx;
  const float ay = y - fy;
  int x0 = static_cast<int>(fx);
  int y0 = static_cast<int>(fy);
  if (x0 < 0) x0 += level.width;
  if (y0 < 0) y0 += level.height;
  if (x0 >= level.width) x0 -= level.width;
  if (y0 >= level.height) y0 -= level.height;
  const int x1 = x0 + 1 == level.width ? 0 : x0 + 1;
  const int y1 = y0 + 1 == level.height ? 0 : y0 + 1;
  const Vector3f* r0 = level.texels.data() + static_cast<size_t>(y0) * level.width;
  const Vector3f* r1 = level.texels.data() + static_cast<size_t>(y1) * level.width;
  return (1.0f - ay) * ((1.0f - ax) * r0[x0] + ax * r0[x1]) + ay * ((1.0f - ax) * r1[x0] + ax * r1[x1]);
}

Vector3f Texture::SampleTrilinear(float u, float v, float level) const {
  if (!std::isfinite(u) || !std::isfinite(v)) return Mean();
  const int last = num_levels() - 1;
  if (level <= 0.0f) return SampleBilinear(levels_[0], u, v);
  if (level >= last) return levels_[last].texels[0];
  const int l0 = static_cast<int>(level);
  const float a = level - l0;
  const Vector3f c0 = SampleBilinear(levels_[l0], u, v);
  if (a < 1e-3f) return c0;
  return (1.0f - a) * c0 + a * SampleBilinear(levels_[l0 + 1], u, v);
}

Vector3f Texture::SampleFiltered(float u, float v, const Vector2f& axis_a, const Vector2f& axis_b) const {
  const float w = static_cast<float>(width());
  const float h = static_cast<float>(height());
  // Footprint axes in texels of level 0.
  const Vector2f a(axis_a.x() * w, axis_a.y() * h);
  const Vector2f b(axis_b.x() * w, axis_b.y() * h);
  const float la = a.norm();
  const float lb = b.norm();
  const Vector2f& major_axis = la >= lb ? axis_a : axis_b;
  const float major = std::max(la, lb);
  const float minor = std::max(std::min(la, lb), 1e-6f);
  if (major <= 1.0f) return SampleTrilinear(u, v, 0.0f);
  const int taps = std::min(kMaxAnisotropy, static_cast<int>(std::ceil(major / minor)));
  // The level of detail covers what the taps do not: the footprint length per tap.
  const float level = std::log2(std::max(1.0f, major / taps));
  if (taps <= 1) return SampleTrilinear(u, v, level);
  Vector3f sum = Vector3f::Zero();
  for (int i = 0; i < taps; ++i) {
    const float s = (i + 0.5f) / taps - 0.5f;
    sum += SampleTrilinear(u + s * major_axis.x(), v + s * major_axis.y(), level);
  }
  return sum / static_cast<float>(taps);
}

Vector3f Texture::Mean() const { return levels_.empty() ? Vector3f(0.5f, 0.5f, 0.5f) : levels_.back().texels[0]; }

}  // namespace retrace
