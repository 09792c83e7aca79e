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

}  // namespace retrace
