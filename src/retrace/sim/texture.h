#pragma once

// Textures of the simulated world, with the filtering that keeps rendered images free of aliasing shimmer.
//
// A texture is an RGB image (linear reflectance in [0, 1]) with a mip-map pyramid (each level the 2x2 box average
// of the one below). A lookup receives the pixel's footprint on the surface in texture coordinates (two axes from
// ray differentials, see renderer.h) and filters like a GPU's anisotropic filter: the level of detail comes from the
// minor axis of the footprint, and up to kMaxAnisotropy trilinear taps are spread along the major axis (Heckbert
// 1989, "Fundamentals of texture mapping"; the EWA-free "feline"-style approximation). So a facade seen at a grazing
// angle stays sharp across the street and never flickers along it.
//
// Texture coordinates (u, v) are in texture widths/heights: u = 1 is the right border, and the texture repeats.

#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace retrace {

using Vector2f = Eigen::Vector2f;
using Vector3f = Eigen::Vector3f;

class Texture {
 public:
  static constexpr int kMaxAnisotropy = 4;

  Texture() = default;
  // `image`: CV_32FC3 in [0, 1] (RGB order) or CV_8UC3 (BGR order, as read by cv::imread). Any size >= 1x1.
  explicit Texture(const cv::Mat& image);

  int width() const { return levels_.empty() ? 0 : levels_[0].width; }
  int height() const { return levels_.empty() ? 0 : levels_[0].height; }
  int num_levels() const { return static_cast<int>(levels_.size()); }

  // Bilinear lookup on mip level `level` (fractional levels in the middle half of an octave blend two levels:
  // trilinear; near whole levels one level alone: "brilinear", continuous in `level` but cheaper).
  Vector3f SampleTrilinear(float u, float v, float level) const;

  // Filtered lookup for a pixel footprint with axes `axis_a` and `axis_b` in texture coordinates (the uv change
  // across the pixel along two directions). Without filtering pass zero axes: level 0, bilinear.
  Vector3f SampleFiltered(float u, float v, const Vector2f& axis_a, const Vector2f& axis_b) const;

  // The same lookups on the luminance (0.2126 R + 0.7152 G + 0.0722 B) only: a third of the work, for grey images.
  float SampleTrilinearGray(float u, float v, float level) const;
  float SampleFilteredGray(float u, float v, const Vector2f& axis_a, const Vector2f& axis_b) const;

  // Average colour (the top level of the pyramid).
  Vector3f Mean() const;

 private:
  struct Level {
    int width = 0;
    int height = 0;
    int stride = 0;                // width + 1: texels and gray have one extra (wrapped) column and row
    std::vector<Vector3f> texels;  // row-major, (width + 1) x (height + 1)
    std::vector<uint8_t> gray;     // luminance of `texels`, x 255 (compact: grey rendering is memory bound)
  };
  // Mean of `taps` trilinear lookups at level `level`, spread evenly along (du, dv) around (u, v).
  template <typename T, typename S>
  T Taps(const std::vector<S> Level::*channel, float u, float v, float du, float dv, int taps, float level) const;
  template <typename T, typename S>
  T Filtered(const std::vector<S> Level::*channel, float u, float v, const Vector2f& axis_a,
             const Vector2f& axis_b) const;

  std::vector<Level> levels_;
};

}  // namespace retrace
