#pragma once

// Binary key-points for relocalization (design §4.2, §6 bootstrap; issue 16): FAST corners on a scale pyramid,
// described by upright rotated-BRIEF (ORB, Rublee et al., ICCV 2011), 32 bytes each (or fewer, below), matched by
// Hamming distance with the same ratio test and cross-check as the SIFT matching of wide_baseline.h (Segvic 2009
// §4.1).
//
// Why not SIFT here: relocalization runs while the robot is lost, every frame, against several key-images. SIFT
// with three detectors (wide_baseline.h) costs 45 ms per 320x240 frame plus 30 ms per key-image whose key-points
// were not extracted yet; ORB costs a few milliseconds per frame, its key-image descriptors are small enough to be
// stored in the map by teach (38 bytes per key-point with its position and size), and a Hamming distance table of
// two 500-key-point images takes well under a millisecond. Verification (a relative pose on the matches) decides,
// not the descriptor: a weaker descriptor gives fewer inliers, never a wrong place accepted on its own.
//
// Upright: cameras on ground vehicles do not roll, so the orientation is fixed at 0 (more distinctive than
// rotation-invariant descriptors for this motion, as upright SIFT in wide_baseline.h).

#include <string>

#include <opencv2/core.hpp>

#include "retrace/feature/wide_baseline.h"

namespace retrace {

struct BinaryFeatureOptions {
  // Key-points kept (strongest Harris score first). Kidnapped starts in the simulated town (320x240, other sun):
  // 500 localized 68 % at the first frame, 1000 93 % (20 inliers).
  int max_keypoints = 1000;
  // With scale_with_area, max_keypoints is for an image of reference_area pixels and scaled by sqrt(image area /
  // reference_area) (a 1226x370 image keeps 2.4 times as many): what a relocalizing frame extracts. Without it
  // (stored key-images) every image keeps max_keypoints at most: 2430 per 1226x370 key-image made kitti07's map
  // 36.7 kB/m, above the paper's 30 kB/m.
  bool scale_with_area = false;
  int reference_area = 320 * 240;
  // Pyramid of the detector: scale factor between levels and number of levels (ORB's defaults).
  double scale_factor = 1.2;
  int levels = 8;
  // FAST threshold (grey levels), ORB's default. 10 found no more of the right key-images in the simulated town
  // (100 kidnapped starts) and cost more.
  int fast_threshold = 20;
  // Side of the described patch and the margin kept from the image border (pixels at level 0), ORB's default: 19
  // localized 90 % of kidnapped starts in the simulated town at the first frame where 31 localized 93 %.
  int patch_size = 31;
  // Matching: ratio test on Hamming distances and cross-check, as MatchWideBaseline. Looser than SIFT's 0.8: Hamming
  // distances of 256 bits are coarse, and 0.85 localized 98 % of the kidnapped starts above at the first frame
  // where 0.8 localized 93 %; the relative pose verifies every match.
  double ratio = 0.85;
  bool cross_check = true;
  // Bytes kept of each 32-byte descriptor (8, 16, 24 or 32): its first 8 x descriptor_bytes binary tests. The
  // map stores them for every key-point of every key-image, most of its size (issue 16: kitti07's 16 key-images
  // keep 1000 key-points each, 512 kB of 32-byte descriptors in a 1.29 MB map). Fewer bits tell a descriptor from
  // its look-alikes less well; the relative pose verifies the matches, but not well enough. 100 kidnapped starts
  // each (`retrace bench kidnap ... --descriptor-bytes N`), localized at the first frame / within 3 frames:
  //   validation seeds 1-3: 32 bytes 92 / 93 / 97 %, 16 bytes 91 / 92 / 98 %, 8 bytes 93 / 94 / 99 % (first);
  //   1264-key-image map, seeds 1-2: 32 bytes 84 / 94 and 80 / 91 %, 16 bytes 85 / 94 and 80 / 92 %, 8 bytes 85 / 93
  //   and 80 / 93 %, 0 wrong; 8 bytes let more chance matches through to the relative pose (the first frame's
  //   95th percentile 136-143 ms CPU against 53-65 ms).
  // But over the validation matrix (scripts/validation) 16 bytes reported 29 frames on a wrong arc, one of them two
  // arcs off (hard127), against 19 and none with 32, for 97.65 % correct instead of 97.54 %: 32 stays the default.
  int descriptor_bytes = 32;

  bool Check(std::string* error = nullptr) const;
  // The settings that make the stored key-image descriptors, e.g. "orb-upright n500 f1.2 l8 t10 p19": maps store
  // it, and descriptors made with other settings are computed again.
  std::string Name() const;
};

// Key-points and binary descriptors of options.descriptor_bytes bytes (CV_8U, one row per key-point) of an 8-bit
// gray image, as WideBaselineFeatures so that MatchWideBaseline matches them (by Hamming distance).
WideBaselineFeatures ExtractBinaryFeatures(const cv::Mat& image, const BinaryFeatureOptions& options = {});

// The descriptors ExtractBinaryFeatures gives `keypoints` of `image` (position, and size, from which the pyramid level
// follows: patch_size · scale_factor^level), one row per key-point in their order; a key-point too near the border to
// be described gets a row of zeros. Maps store key-image descriptors as their differences from these, computed on
// the key-image as stored (map/descriptor_coding.h).
cv::Mat DescribeBinaryKeyPoints(const cv::Mat& image, const std::vector<cv::KeyPoint>& keypoints,
                                const BinaryFeatureOptions& options = {});

// MatchWideBaseline with the ratio and cross-check of `options`.
std::vector<cv::DMatch> MatchBinary(const WideBaselineFeatures& query, const WideBaselineFeatures& train,
                                    const BinaryFeatureOptions& options = {});

}  // namespace retrace
