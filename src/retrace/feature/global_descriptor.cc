#include "retrace/feature/global_descriptor.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
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

std::string GlobalDescriptorOptions::Name() const {
  return "thumbnail w" + std::to_string(width) + " p" + std::to_string(patch_size);
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

cv::Mat QuantizeGlobalDescriptor(const GlobalDescriptor& descriptor) {
  if (descriptor.empty()) throw std::invalid_argument("QuantizeGlobalDescriptor: empty descriptor");
  cv::Mat quantised;
  // round(32 v) + 128, saturated to 0..255.
  descriptor.thumbnail.convertTo(quantised, CV_8U, 32.0, 128.0);
  return quantised;
}

GlobalDescriptor DequantizeGlobalDescriptor(const cv::Mat& quantised) {
  if (quantised.empty() || quantised.type() != CV_8UC1) {
    throw std::invalid_argument("DequantizeGlobalDescriptor: needs a CV_8U thumbnail");
  }
  GlobalDescriptor descriptor;
  quantised.convertTo(descriptor.thumbnail, CV_32F, 1.0 / 32.0, -128.0 / 32.0);
  return descriptor;
}

size_t AppearanceIndex::Add(const cv::Mat& quantised) {
  if (quantised.empty() || quantised.type() != CV_8UC1) throw std::invalid_argument("AppearanceIndex: needs CV_8U");
  if (count_ == 0) {
    rows_ = quantised.rows;
    cols_ = quantised.cols;
  } else if (quantised.rows != rows_ || quantised.cols != cols_) {
    throw std::invalid_argument("AppearanceIndex: descriptors of different sizes");
  }
  for (int r = 0; r < rows_; ++r) data_.insert(data_.end(), quantised.ptr<uint8_t>(r), quantised.ptr<uint8_t>(r) + cols_);
  return count_++;
}

namespace {

// Sum of |a[i] - b[i]| over n bytes: the loop GCC and Clang vectorise into SIMD sums of absolute differences.
inline uint32_t SumOfAbsoluteDifferences(const uint8_t* a, const uint8_t* b, int n) {
  uint32_t sum = 0;
  for (int i = 0; i < n; ++i) sum += static_cast<uint32_t>(std::abs(static_cast<int>(a[i]) - static_cast<int>(b[i])));
  return sum;
}

}  // namespace

double AppearanceIndex::Distance(const cv::Mat& quantised_query, size_t index) const {
  if (index >= count_) throw std::out_of_range("AppearanceIndex: no entry " + std::to_string(index));
  if (quantised_query.type() != CV_8UC1 || quantised_query.rows != rows_ || quantised_query.cols != cols_) {
    throw std::invalid_argument("AppearanceIndex: query of another size or type");
  }
  const cv::Mat query = quantised_query.isContinuous() ? quantised_query : quantised_query.clone();
  const uint8_t* entry = data_.data() + index * static_cast<size_t>(rows_) * cols_;
  const int max_shift = std::min(options_.max_shift, cols_ / 2 - 1);
  double best = std::numeric_limits<double>::infinity();
  // As GlobalDescriptorDistance: column x of the query against column x - shift of the entry, over the overlap.
  for (int shift = -max_shift; shift <= max_shift; ++shift) {
    const int begin = std::max(0, shift);
    const int end = std::min(cols_, cols_ + shift);
    uint64_t sum = 0;
    for (int r = 0; r < rows_; ++r) {
      sum += SumOfAbsoluteDifferences(query.ptr<uint8_t>(r) + begin, entry + r * cols_ + begin - shift, end - begin);
    }
    best = std::min(best, static_cast<double>(sum) / (32.0 * rows_ * (end - begin)));
  }
  return best;
}

std::vector<size_t> AppearanceIndex::Rank(const cv::Mat& quantised_query, const std::vector<size_t>& subset) const {
  std::vector<double> distances(subset.size());
  for (size_t i = 0; i < subset.size(); ++i) distances[i] = Distance(quantised_query, subset[i]);
  std::vector<size_t> order(subset.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&distances](size_t x, size_t y) { return distances[x] < distances[y]; });
  for (size_t& o : order) o = subset[o];
  return order;
}

}  // namespace retrace
