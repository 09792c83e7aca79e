#include "retrace/feature/global_descriptor.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

#include <opencv2/imgproc.hpp>

namespace retrace {

bool GlobalDescriptorOptions::Check(std::string* error) const {
  const auto fail = [error](const char* message) {
    if (error != nullptr) *error = message;
    return false;
  };
  if (width < 8) return fail("width must be >= 8");
  if (patch_size < 3 || patch_size % 2 == 0) return fail("patch_size must be odd and >= 3");
  if (max_shift < 0 || max_shift >= width / 2) return fail("max_shift must be in [0, width / 2)");
  return true;
}

GlobalDescriptor ComputeGlobalDescriptor(const cv::Mat& image, const GlobalDescriptorOptions& options) {
  std::string error;
  if (!options.Check(&error)) throw std::invalid_argument("GlobalDescriptorOptions: " + error);
  if (image.empty() || image.type() != CV_8UC1)
    throw std::invalid_argument("ComputeGlobalDescriptor: needs 8-bit gray");
  const int height = std::max(8, static_cast<int>(std::lround(options.width * double(image.rows) / image.cols)));
  cv::Mat thumbnail;
  cv::resize(image, thumbnail, cv::Size(options.width, height), 0, 0, cv::INTER_AREA);
  thumbnail.convertTo(thumbnail, CV_32F);

  // Patch normalisation (SeqSLAM §III-A): (I - local mean) / local standard deviation. The deviation is floored at
  // one grey level so that flat regions (sky, blank walls) stay flat instead of amplifying noise.
  const cv::Size patch(options.patch_size, options.patch_size);
  cv::Mat mean, mean_of_squares;
  cv::boxFilter(thumbnail, mean, CV_32F, patch, cv::Point(-1, -1), true, cv::BORDER_REFLECT);
  cv::boxFilter(thumbnail.mul(thumbnail), mean_of_squares, CV_32F, patch, cv::Point(-1, -1), true,
                cv::BORDER_REFLECT);
  cv::Mat deviation;
  cv::sqrt(cv::max(mean_of_squares - mean.mul(mean), 1.0), deviation);
  GlobalDescriptor descriptor;
  descriptor.thumbnail = (thumbnail - mean) / deviation;
  return descriptor;
}

double GlobalDescriptorDistance(const GlobalDescriptor& a, const GlobalDescriptor& b,
                                const GlobalDescriptorOptions& options) {
  if (a.empty() || b.empty() || a.thumbnail.size() != b.thumbnail.size()) {
    throw std::invalid_argument("GlobalDescriptorDistance: descriptors of different sizes");
  }
  const int cols = a.thumbnail.cols;
  const int max_shift = std::min(options.max_shift, cols / 2 - 1);
  double best = std::numeric_limits<double>::infinity();
  for (int shift = -max_shift; shift <= max_shift; ++shift) {
    // Column x of a against column x - shift of b, over their overlap.
    const int begin = std::max(0, shift);
    const int end = std::min(cols, cols + shift);
    const cv::Mat overlap_a = a.thumbnail.colRange(begin, end);
    const cv::Mat overlap_b = b.thumbnail.colRange(begin - shift, end - shift);
    best = std::min(best, cv::norm(overlap_a, overlap_b, cv::NORM_L1) / double(overlap_a.total()));
  }
  return best;
}

std::vector<size_t> RankByGlobalDescriptor(const GlobalDescriptor& query, const std::vector<GlobalDescriptor>& database,
                                           const GlobalDescriptorOptions& options) {
  std::vector<double> distances(database.size());
  for (size_t i = 0; i < database.size(); ++i) distances[i] = GlobalDescriptorDistance(query, database[i], options);
  std::vector<size_t> order(database.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&distances](size_t x, size_t y) { return distances[x] < distances[y]; });
  return order;
}

}  // namespace retrace
