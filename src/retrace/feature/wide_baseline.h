#pragma once

// Wide-baseline matching (Segvic 2009 §4.1, design §4.2): no assumption on the relative pose of the two images.
//
// Key-points come from three detectors that respond to different structures — difference of Gaussians (SIFT's
// detector), multi-scale Harris corners and MSER regions — and all of them are described by SIFT descriptors.
// The three sets are fused by dropping a key-point that lies within a few pixels of one already kept at a similar
// scale. Matches are nearest neighbours in L2 whose distance is below `ratio` times the distance to the second
// nearest: 0.6 in the paper, strict because urban scenes repeat the same structure (windows, fences) so often.
//
// Used for everything the differential tracker cannot do: bootstrap and relocalization of repeat, gap recovery and
// loop closing in teach, joining routes.

#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>

namespace retrace {

struct WideBaselineOptions {
  // Difference-of-Gaussians (SIFT) key-points kept, strongest first; 0 disables the detector.
  int max_dog_keypoints = 1500;
  // Multi-scale Harris corners kept over all levels; 0 disables the detector.
  int max_harris_keypoints = 1000;
  // Pyramid levels (factor 2) on which Harris corners are detected.
  int harris_levels = 3;
  // Harris corners weaker than this fraction of the strongest one on their level are ignored.
  double harris_quality = 0.01;
  // MSER regions kept, largest stability first; 0 disables the detector.
  int max_mser_keypoints = 500;
  // A key-point closer than this (pixels) to an already kept key-point of similar scale is dropped (fusion).
  double fusion_radius_px = 3.0;
  // Segvic 2009 §4.1: keep a match when best distance < ratio * second-best distance.
  double ratio = 0.6;
  // Keep only matches that are also the best match in the other direction.
  bool cross_check = true;
  // Describe every key-point with orientation 0 (upright SIFT). Right for cameras on ground vehicles, which do not
  // roll; switch off for hand-held cameras.
  bool upright = true;

  bool Check(std::string* error = nullptr) const;
};

// Which detector produced a key-point; stored in cv::KeyPoint::class_id.
enum class WideBaselineDetector : int { kDoG = 0, kHarris = 1, kMser = 2 };

struct WideBaselineFeatures {
  std::vector<cv::KeyPoint> keypoints;
  // One descriptor per key-point, same order: CV_32F SIFT (128 values), or CV_8U binary (8-32 bytes,
  // binary_features.h).
  cv::Mat descriptors;

  size_t size() const { return keypoints.size(); }
};

// Detects, fuses and describes key-points of an 8-bit gray image.
WideBaselineFeatures ExtractWideBaselineFeatures(const cv::Mat& image, const WideBaselineOptions& options = {});

// Ratio-tested (and optionally cross-checked) matches; queryIdx indexes `query`, trainIdx indexes `train`. SIFT
// descriptors are compared by L2 distance, binary ones by Hamming distance (both sides must be of one kind).
std::vector<cv::DMatch> MatchWideBaseline(const WideBaselineFeatures& query, const WideBaselineFeatures& train,
                                          const WideBaselineOptions& options = {});

// Guided matching along epipolar lines (Hartley & Zisserman, "Multiple View Geometry", 2nd ed., §11.9): given a
// relative pose that a few matches support, each query key-point is matched among the train key-points whose
// bearings lie within `max_angle` (radians) of its epipolar plane, x_tᵀ E x_q = 0 with E = [t]ₓ R of
// train_from_query. The ratio test (options.ratio, Segvic 2009 §4.1) then compares the best with the second best
// within that band only, so texture repeated elsewhere in the image no longer hides a match; each train key-point
// keeps its best query. Bearings of zero length (not unprojectable) are skipped. Binary descriptors only.
std::vector<cv::DMatch> MatchAlongEpipolarPlanes(const WideBaselineFeatures& query, const WideBaselineFeatures& train,
                                                 const std::vector<Eigen::Vector3d>& query_bearings,
                                                 const std::vector<Eigen::Vector3d>& train_bearings,
                                                 const Eigen::Matrix3d& essential, double max_angle,
                                                 const WideBaselineOptions& options);

}  // namespace retrace
