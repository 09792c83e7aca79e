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

void ImagePyramid::Build(const cv::Mat& image, const ImagePyramidOptions& options) {
  if (!options.Check()) throw std::invalid_argument("ImagePyramid: invalid options");
  if (image.empty() || image.channels() != 1 || (image.depth() != CV_8U && image.depth() != CV_32F)) {
    throw std::invalid_argument("ImagePyramid: expected a non-empty single-channel CV_8U or CV_32F image");
  }
  options_ = options;
  levels_.resize(options.num_levels);
  // Level 0: float conversion, then Gaussian pre-smoothing with a kernel of +-3 sigma.
  const cv::Mat* source = &image;
  if (image.depth() != CV_32F) {
    image.convertTo(input_float_, CV_32F);
    source = &input_float_;
  }
  if (options.smoothing_sigma > 0.0) {
    const int radius = std::max(1, static_cast<int>(std::ceil(3.0 * options.smoothing_sigma)));
    cv::GaussianBlur(*source, levels_[0], cv::Size(2 * radius + 1, 2 * radius + 1), options.smoothing_sigma,
                     options.smoothing_sigma, cv::BORDER_REFLECT_101);
  } else {
    source->copyTo(levels_[0]);
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
