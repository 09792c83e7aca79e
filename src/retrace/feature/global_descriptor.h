#pragma once

// A whole-image appearance descriptor for ranking key-images before wide-baseline verification (design §6,
// bootstrap "image retrieval over all key-images + geometric verification").
//
// The image is shrunk to a thumbnail a few dozen pixels wide and every thumbnail pixel is normalised by the mean
// and standard deviation of its neighbourhood ("patch normalisation", Milford & Wyeth 2012, SeqSLAM §III-A), which
// removes slow changes of brightness and contrast (another sun, another exposure). Two thumbnails are compared by
// the mean absolute difference of their overlap, minimised over small horizontal shifts: a robot repeating a route
// drives a little to the side and heads a few degrees off. A thumbnail keeps the layout of the scene (where the
// sky, the facades and the road are), which wide-baseline key-points do not; it ranks places, it does not verify
// them.
//
// Ranking only: on the simulated towns (seven drives, 1 m offset, other sun) the key-image at the place or a
// neighbour of it is the closest thumbnail for 84 % of the frames and among the closest eight for 98 %.

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace retrace {

struct GlobalDescriptorOptions {
  // Width of the thumbnail (pixels); the height follows the image's aspect ratio (at least 8 rows).
  int width = 48;
  // Side of the square neighbourhood of the patch normalisation (thumbnail pixels, odd).
  int patch_size = 9;
  // Largest horizontal shift (thumbnail pixels) tried when comparing two descriptors.
  int max_shift = 3;

  bool Check(std::string* error = nullptr) const;
  // The settings that make a descriptor's values, e.g. "thumbnail w48 p9" (max_shift only affects comparisons):
  // maps store it with the key-images' quantised descriptors.
  std::string Name() const;
};

struct GlobalDescriptor {
  cv::Mat thumbnail;  // CV_32F, patch-normalised

  bool empty() const { return thumbnail.empty(); }
};

// The descriptor of an 8-bit gray image.
GlobalDescriptor ComputeGlobalDescriptor(const cv::Mat& image, const GlobalDescriptorOptions& options = {});

// Dissimilarity of two descriptors made with the same options: the smallest mean absolute difference of the
// normalised thumbnails over horizontal shifts up to `options.max_shift` (0 for identical images; about 1.1 for
// unrelated ones, the mean absolute difference of two independent unit-variance signals).
double GlobalDescriptorDistance(const GlobalDescriptor& a, const GlobalDescriptor& b,
                                const GlobalDescriptorOptions& options = {});

// Indices of `database` ordered from the most to the least similar to `query` (ties keep the database order).
std::vector<size_t> RankByGlobalDescriptor(const GlobalDescriptor& query, const std::vector<GlobalDescriptor>& database,
                                           const GlobalDescriptorOptions& options = {});

// Quantised descriptors and a retrieval index over many key-images (issue 16: thousands of key-images in a few
// milliseconds). A key-image's thumbnail is stored in the map as one byte per pixel: round(32 v) + 128, clamped to
// 0..255, i.e. patch-normalised values within ±4 standard deviations at 1/32 resolution (1728 bytes at the default
// 48x36 instead of 6912). Distances are the same measure as GlobalDescriptorDistance (mean absolute difference of
// the overlap, minimised over horizontal shifts), computed on the bytes with integer sums, which the compiler turns
// into SIMD sums of absolute differences: an exhaustive scan of 4000 key-images takes about a millisecond
// (BM_AppearanceIndexRank), so no approximate index (faiss, inverted files) is needed at the sizes retrace maps.
cv::Mat QuantizeGlobalDescriptor(const GlobalDescriptor& descriptor);  // CV_8U, the thumbnail's size
GlobalDescriptor DequantizeGlobalDescriptor(const cv::Mat& quantised);

class AppearanceIndex {
 public:
  explicit AppearanceIndex(const GlobalDescriptorOptions& options = {}) : options_(options) {}

  // Adds a quantised descriptor (QuantizeGlobalDescriptor) and returns its index (0, 1, ...). All descriptors of an
  // index have one size; throws std::invalid_argument for another.
  size_t Add(const cv::Mat& quantised);
  size_t size() const { return count_; }

  // Dissimilarity of `quantised_query` to entry `index`, in the units of GlobalDescriptorDistance.
  double Distance(const cv::Mat& quantised_query, size_t index) const;
  // The entries `subset` (indices of Add) ordered from the most to the least similar to the query (ties keep the
  // order of `subset`).
  std::vector<size_t> Rank(const cv::Mat& quantised_query, const std::vector<size_t>& subset) const;

 private:
  GlobalDescriptorOptions options_;
  int rows_ = 0, cols_ = 0;
  size_t count_ = 0;
  std::vector<uint8_t> data_;  // count_ thumbnails of rows_ x cols_ bytes, row-major
};

}  // namespace retrace
