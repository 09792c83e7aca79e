#include "retrace/feature/synthetic_texture.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

namespace retrace {
namespace {

// Blurred step: fraction of a Gaussian (std sigma) on the positive side of 0, at signed distance d.
inline double Ramp(double d, double inv_sigma_sqrt2) { return 0.5 * std::erfc(-d * inv_sigma_sqrt2); }

}  // namespace

SyntheticTexture::SyntheticTexture(const SyntheticTextureOptions& options) : options_(options) {
  if (!options.Check()) throw std::invalid_argument("SyntheticTexture: invalid options");
  std::mt19937_64 rng(options.seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  background_fx_ = 2.0 * M_PI * (0.5 + 1.5 * unit(rng)) / options.width;
  background_fy_ = 2.0 * M_PI * (0.5 + 1.5 * unit(rng)) / options.height;
  background_px_ = 2.0 * M_PI * unit(rng);
  background_py_ = 2.0 * M_PI * unit(rng);
  const double mean_size = std::sqrt(options.width * options.height / std::max(1, options.num_shapes)) * 0.9;
  for (int i = 0; i < options.num_shapes; ++i) {
    Shape shape;
    shape.grey = unit(rng);
    const double cx = unit(rng) * options.width, cy = unit(rng) * options.height;
    const double size = mean_size * (0.3 + 1.2 * unit(rng));
    shape.disc = unit(rng) < 0.3;
    if (shape.disc) {
      shape.x0 = cx;
      shape.y0 = cy;
      shape.x1 = 0.4 * size;
    } else {
      shape.x0 = cx;
      shape.y0 = cy;
      shape.x1 = cx + size;
      shape.y1 = cy + size * (0.4 + unit(rng));
    }
    shapes_.push_back(shape);
  }
}

cv::Mat SyntheticTexture::Render(int width, int height, double scale, const Vector2d& translation,
                                 double gain, double bias) const {
  cv::Mat canvas(height, width, CV_64FC1);
  // Background.
  for (int y = 0; y < height; ++y) {
    double* row = canvas.ptr<double>(y);
    const double ty = (y - translation.y()) / scale;
    for (int x = 0; x < width; ++x) {
      const double tx = (x - translation.x()) / scale;
      row[x] = 0.5 + 0.15 * std::sin(background_fx_ * tx + background_px_) *
                         std::cos(background_fy_ * ty + background_py_);
    }
  }
  const double sigma = options_.edge_sigma;
  const double k = 1.0 / (sigma * std::sqrt(2.0));
  const double margin = 4.0 * sigma;
  for (const Shape& s : shapes_) {
    double bx0, by0, bx1, by1;  // bounding box in texture units
    if (s.disc) {
      bx0 = s.x0 - s.x1 - margin;
      bx1 = s.x0 + s.x1 + margin;
      by0 = s.y0 - s.x1 - margin;
      by1 = s.y0 + s.x1 + margin;
    } else {
      bx0 = s.x0 - margin;
      bx1 = s.x1 + margin;
      by0 = s.y0 - margin;
      by1 = s.y1 + margin;
    }
    const int px0 = std::max(0, static_cast<int>(std::floor(scale * bx0 + translation.x())));
    const int px1 = std::min(width - 1, static_cast<int>(std::ceil(scale * bx1 + translation.x())));
    const int py0 = std::max(0, static_cast<int>(std::floor(scale * by0 + translation.y())));
    const int py1 = std::min(height - 1, static_cast<int>(std::ceil(scale * by1 + translation.y())));
    for (int y = py0; y <= py1; ++y) {
      double* row = canvas.ptr<double>(y);
      const double ty = (y - translation.y()) / scale;
      const double my = s.disc ? 0.0 : Ramp(ty - s.y0, k) * Ramp(s.y1 - ty, k);
      for (int x = px0; x <= px1; ++x) {
        const double tx = (x - translation.x()) / scale;
        const double m = s.disc ? Ramp(s.x1 - std::hypot(tx - s.x0, ty - s.y0), k)
                                : my * Ramp(tx - s.x0, k) * Ramp(s.x1 - tx, k);
        row[x] += m * (s.grey - row[x]);
      }
    }
  }
  cv::Mat image;
  const double range = options_.max_grey - options_.min_grey;
  canvas.convertTo(image, CV_32F, gain * range, gain * options_.min_grey + bias);
  return image;
}

cv::Mat ClutteredTexture(int width, int height, uint64_t seed) {
  SyntheticTextureOptions options;
  options.width = width;
  options.height = height;
  options.num_shapes = std::max(4, width * height / 500);
  options.min_grey = 10;
  options.max_grey = 240;
  options.seed = seed;
  cv::Mat image;
  SyntheticTexture(options).Render(width, height).convertTo(image, CV_8U);
  return image;
}

}  // namespace retrace
