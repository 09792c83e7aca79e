#include "retrace/feature/image_pyramid.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace retrace {

ImagePyramid::ImagePyramid(const cv::Mat& image, const ImagePyramidOptions& options) {
  Build(image, options);
}

ImagePyramid ImagePyramid::FinestLevels(int num_levels) const {
  ImagePyramid view;
  view.options_ = options_;
  if (levels_.empty()) return view;
  const int kept = std::clamp(num_levels, 1, NumLevels());
  view.options_.num_levels = kept;
  view.levels_.assign(levels_.begin(), levels_.begin() + kept);
  return view;
}

namespace {
// OpenCV's separable filter sums symmetric kernels of up to this many taps by a path of their own when the input is
// float (SymmRowSmall*), not when it is 8-bit.
constexpr int kMaxSmallKernelSize = 5;
}  // namespace

void ImagePyramid::Build(const cv::Mat& image, const ImagePyramidOptions& options) {
  if (!options.Check()) throw std::invalid_argument("ImagePyramid: invalid options");
  if (image.empty() || image.channels() != 1 || (image.depth() != CV_8U && image.depth() != CV_32F)) {
    throw std::invalid_argument("ImagePyramid: expected a non-empty single-channel CV_8U or CV_32F image");
  }
  options_ = options;
  levels_.resize(options.num_levels);
  // Level 0: float conversion, then Gaussian pre-smoothing with a kernel of +-3 sigma.
  const int radius = std::max(1, static_cast<int>(std::ceil(3.0 * options.smoothing_sigma)));
  const int kernel_size = 2 * radius + 1;
  if (options.smoothing_sigma > 0.0 && image.depth() == CV_8U && kernel_size > kMaxSmallKernelSize) {
    // The separable filter reads the 8-bit image and writes float: no float copy of the input (a quarter of the
    // pre-smoothing's time at 1226x370). The same values as converting first: each output is the same sum of the
    // same float products in the same order (OpenCV's row filter from 8 bits and from float differ only in how they
    // load a pixel, exactly representable either way); in float, OpenCV sums kernels of up to 5 taps another way,
    // which is why those convert first. ImagePyramid.EightBitInputGivesTheFloatInputsLevels checks it.
    const cv::Mat kernel = cv::getGaussianKernel(kernel_size, options.smoothing_sigma, CV_32F);
    cv::sepFilter2D(image, levels_[0], CV_32F, kernel, kernel, cv::Point(-1, -1), 0.0, cv::BORDER_REFLECT_101);
  } else {
    const cv::Mat* source = &image;
    if (image.depth() != CV_32F) {
      image.convertTo(input_float_, CV_32F);
      source = &input_float_;
    }
    if (options.smoothing_sigma > 0.0) {
      cv::GaussianBlur(*source, levels_[0], cv::Size(kernel_size, kernel_size), options.smoothing_sigma,
                       options.smoothing_sigma, cv::BORDER_REFLECT_101);
    } else {
      source->copyTo(levels_[0]);
    }
  }
  for (int l = 1; l < options.num_levels; ++l) {
    cv::pyrDown(levels_[l - 1], levels_[l]);
  }
}

ImagePyramidOptions TrackingPyramidOptions(int width, int reference_width, double smoothing_sigma_px) {
  const double pixel_scale = static_cast<double>(width) / std::max(1, reference_width);
  ImagePyramidOptions options;
  options.smoothing_sigma = smoothing_sigma_px * pixel_scale;
  options.num_levels = 3 + std::max(0, static_cast<int>(std::floor(std::log2(pixel_scale) + 0.25)));
  return options;
}

}  // namespace retrace
