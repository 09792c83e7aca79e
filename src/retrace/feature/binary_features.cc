#include "retrace/feature/binary_features.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <opencv2/features2d.hpp>

namespace retrace {

bool BinaryFeatureOptions::Check(std::string* error) const {
  const auto fail = [error](const char* message) {
    if (error != nullptr) *error = message;
    return false;
  };
  if (max_keypoints < 8) return fail("max_keypoints must be >= 8");
  if (reference_area < 1) return fail("reference_area must be positive");
  if (!(scale_factor > 1.0 && scale_factor <= 2.0)) return fail("scale_factor must be in (1, 2]");
  if (levels < 1 || levels > 16) return fail("levels must be in 1..16");
  if (fast_threshold < 1 || fast_threshold > 255) return fail("fast_threshold must be in 1..255");
  if (patch_size < 7 || patch_size > 63) return fail("patch_size must be in 7..63");
  if (!(ratio > 0.0 && ratio <= 1.0)) return fail("ratio must be in (0, 1]");
  if (descriptor_bytes < 8 || descriptor_bytes > 32 || descriptor_bytes % 8 != 0) {
    return fail("descriptor_bytes must be 8, 16, 24 or 32");
  }
  return true;
}

std::string BinaryFeatureOptions::Name() const {
  // Descriptors of 32 bytes are named as before descriptor_bytes existed: the signatures of those maps stay valid.
  return fmt::format("orb-upright n{}{} f{} l{} t{} p{}{}", max_keypoints,
                     scale_with_area ? fmt::format(" a{}", reference_area) : std::string(), scale_factor, levels,
                     fast_threshold, patch_size, descriptor_bytes != 32 ? fmt::format(" b{}", descriptor_bytes) : "");
}

WideBaselineFeatures ExtractBinaryFeatures(const cv::Mat& image, const BinaryFeatureOptions& options) {
  CV_Assert(image.type() == CV_8UC1);
  std::string error;
  if (!options.Check(&error)) throw std::invalid_argument("BinaryFeatureOptions: " + error);
  const double area_ratio =
      options.scale_with_area ? static_cast<double>(image.total()) / options.reference_area : 1.0;
  const int n = std::max(8, static_cast<int>(std::lround(options.max_keypoints * std::sqrt(area_ratio))));
  const cv::Ptr<cv::ORB> orb =
      cv::ORB::create(n, static_cast<float>(options.scale_factor), options.levels, options.patch_size,
                      /*firstLevel=*/0, /*WTA_K=*/2, cv::ORB::HARRIS_SCORE, options.patch_size, options.fast_threshold);
  WideBaselineFeatures features;
  orb->detect(image, features.keypoints);
  // Upright: describe every key-point at orientation 0 (the provided key-points keep their level and position).
  for (cv::KeyPoint& k : features.keypoints) k.angle = 0.0f;
  if (!features.keypoints.empty()) orb->compute(image, features.keypoints, features.descriptors);
  if (features.descriptors.empty()) {
    features.keypoints.clear();
    features.descriptors = cv::Mat(0, options.descriptor_bytes, CV_8U);
  } else if (options.descriptor_bytes < features.descriptors.cols) {
    features.descriptors = features.descriptors.colRange(0, options.descriptor_bytes).clone();
  }
  return features;
}

cv::Mat DescribeBinaryKeyPoints(const cv::Mat& image, const std::vector<cv::KeyPoint>& keypoints,
                                const BinaryFeatureOptions& options) {
  CV_Assert(image.type() == CV_8UC1);
  std::string error;
  if (!options.Check(&error)) throw std::invalid_argument("BinaryFeatureOptions: " + error);
  cv::Mat descriptors = cv::Mat::zeros(static_cast<int>(keypoints.size()), options.descriptor_bytes, CV_8U);
  if (keypoints.empty()) return descriptors;
  const cv::Ptr<cv::ORB> orb = cv::ORB::create(
      static_cast<int>(keypoints.size()), static_cast<float>(options.scale_factor), options.levels, options.patch_size,
      /*firstLevel=*/0, /*WTA_K=*/2, cv::ORB::HARRIS_SCORE, options.patch_size, options.fast_threshold);
  // ORB describes each key-point on its pyramid level (octave) at orientation 0 (upright, as extracted); it may drop
  // key-points near the border, so each carries its index.
  std::vector<cv::KeyPoint> described(keypoints);
  const double log_scale = std::log(options.scale_factor);
  for (size_t i = 0; i < described.size(); ++i) {
    cv::KeyPoint& k = described[i];
    const double level = k.size > 0 ? std::log(k.size / options.patch_size) / log_scale : 0.0;
    k.octave = std::clamp(static_cast<int>(std::lround(level)), 0, options.levels - 1);
    k.angle = 0.0f;
    k.class_id = static_cast<int>(i);
  }
  cv::Mat computed;
  orb->compute(image, described, computed);
  for (size_t j = 0; j < described.size() && static_cast<int>(j) < computed.rows; ++j) {
    computed.row(static_cast<int>(j))
        .colRange(0, options.descriptor_bytes)
        .copyTo(descriptors.row(described[j].class_id));
  }
  return descriptors;
}

std::vector<cv::DMatch> MatchBinary(const WideBaselineFeatures& query, const WideBaselineFeatures& train,
                                    const BinaryFeatureOptions& options) {
  WideBaselineOptions matching;
  matching.ratio = options.ratio;
  matching.cross_check = options.cross_check;
  return MatchWideBaseline(query, train, matching);
}

}  // namespace retrace
