#include "retrace/feature/wide_baseline.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Core>

#include <opencv2/core/hal/hal.hpp>
#include <opencv2/imgproc.hpp>

#include "retrace/feature/hamming_nearest.h"

namespace retrace {
namespace {

// Size (diameter in pixels) given to Harris key-points at pyramid level 0; doubles with every level.
constexpr float kHarrisKeypointSize = 12.0f;

std::vector<cv::KeyPoint> DetectDoG(const cv::Mat& image, const WideBaselineOptions& options) {
  std::vector<cv::KeyPoint> keypoints;
  if (options.max_dog_keypoints <= 0) return keypoints;
  cv::SIFT::create(options.max_dog_keypoints)->detect(image, keypoints);
  for (cv::KeyPoint& k : keypoints) k.class_id = static_cast<int>(WideBaselineDetector::kDoG);
  return keypoints;
}

std::vector<cv::KeyPoint> DetectMultiScaleHarris(const cv::Mat& image, const WideBaselineOptions& options) {
  std::vector<cv::KeyPoint> keypoints;
  if (options.max_harris_keypoints <= 0) return keypoints;
  cv::Mat level = image;
  const int per_level = std::max(1, options.max_harris_keypoints / std::max(1, options.harris_levels));
  for (int l = 0; l < options.harris_levels && std::min(level.cols, level.rows) >= 32; ++l) {
    std::vector<cv::Point2f> corners;
    cv::goodFeaturesToTrack(level, corners, per_level, options.harris_quality, /*minDistance=*/5.0, cv::noArray(),
                            /*blockSize=*/3, /*useHarrisDetector=*/true, /*k=*/0.04);
    const float factor = static_cast<float>(1 << l);
    for (const cv::Point2f& c : corners) {
      // Level pixel centres map back to level-0 coordinates as (x + 0.5) * 2^l - 0.5.
      cv::KeyPoint k(cv::Point2f((c.x + 0.5f) * factor - 0.5f, (c.y + 0.5f) * factor - 0.5f),
                     kHarrisKeypointSize * factor);
      k.octave = l;
      k.class_id = static_cast<int>(WideBaselineDetector::kHarris);
      keypoints.push_back(k);
    }
    cv::Mat next;
    cv::pyrDown(level, next);
    level = next;
  }
  return keypoints;
}

std::vector<cv::KeyPoint> DetectMser(const cv::Mat& image, const WideBaselineOptions& options) {
  std::vector<cv::KeyPoint> keypoints;
  if (options.max_mser_keypoints <= 0) return keypoints;
  std::vector<std::vector<cv::Point>> regions;
  std::vector<cv::Rect> boxes;
  cv::MSER::create(/*delta=*/5, /*min_area=*/30, /*max_area=*/static_cast<int>(0.01 * image.total()))
      ->detectRegions(image, regions, boxes);
  for (const std::vector<cv::Point>& region : regions) {
    cv::Point2d centroid(0.0, 0.0);
    for (const cv::Point& p : region) centroid += cv::Point2d(p.x, p.y);
    centroid *= 1.0 / region.size();
    // Diameter of the disc with the region's area.
    const float size = static_cast<float>(2.0 * std::sqrt(region.size() / M_PI));
    cv::KeyPoint k(cv::Point2f(static_cast<float>(centroid.x), static_cast<float>(centroid.y)), size);
    k.response = static_cast<float>(region.size());
    k.class_id = static_cast<int>(WideBaselineDetector::kMser);
    keypoints.push_back(k);
  }
  std::sort(keypoints.begin(), keypoints.end(),
            [](const cv::KeyPoint& a, const cv::KeyPoint& b) { return a.response > b.response; });
  if (keypoints.size() > static_cast<size_t>(options.max_mser_keypoints)) {
    keypoints.resize(options.max_mser_keypoints);
  }
  return keypoints;
}

// Appends `candidates` to `kept`, skipping those within `radius` of a kept key-point of similar scale (size ratio
// below 2). A uniform grid of cell `radius` makes the test local.
void FuseInto(const std::vector<cv::KeyPoint>& candidates, double radius, std::vector<cv::KeyPoint>* kept, std::vector<std::vector<int>>* grid, int grid_cols) {
  const auto cell_of = [&](const cv::Point2f& p) {
    const int cx = std::clamp(static_cast<int>(p.x / radius), 0, grid_cols - 1);
    const int cy = std::clamp(static_cast<int>(p.y / radius), 0, static_cast<int>(grid->size() / grid_cols) - 1);
    return std::pair<int, int>(cx, cy);
  };
  const int grid_rows = static_cast<int>(grid->size() / grid_cols);
  for (const cv::KeyPoint& candidate : candidates) {
    const auto [cx, cy] = cell_of(candidate.pt);
    bool duplicate = false;
    for (int y = std::max(0, cy - 1); y <= std::min(grid_rows - 1, cy + 1) && !duplicate; ++y) {
      for (int x = std::max(0, cx - 1); x <= std::min(grid_cols - 1, cx + 1) && !duplicate; ++x) {
        for (int index : (*grid)[y * grid_cols + x]) {
          const cv::KeyPoint& other = (*kept)[index];
          const float ratio = std::max(candidate.size, other.size) / std::max(1e-3f, std::min(candidate.size, other.size));
          if (cv::norm(candidate.pt - other.pt) < radius && ratio < 2.0f) {
            duplicate = true;
            break;
          }
        }
      }
    }
    if (duplicate) continue;
    (*grid)[cy * grid_cols + cx].push_back(static_cast<int>(kept->size()));
    kept->push_back(candidate);
  }
}

// Binary descriptors (binary_features.h): the nearest descriptors by Hamming distance, then the same ratio test and
// cross-check as for SIFT.
std::vector<cv::DMatch> MatchBinaryDescriptors(const cv::Mat& query, const cv::Mat& train,
                                               const WideBaselineOptions& options) {
  const HammingNearest nearest = FindHammingNearest(query, train);
  std::vector<cv::DMatch> matches;
  for (int i = 0; i < query.rows; ++i) {
    const int best = nearest.best[i];
    // Segvic 2009 §4.1 on distances (not squared distances as for SIFT).
    if (best < 0 || !(nearest.best_d[i] < options.ratio * nearest.second_d[i])) continue;
    if (options.cross_check && nearest.best_query_of_train[best] != i) continue;
    matches.emplace_back(i, best, static_cast<float>(nearest.best_d[i]));
  }
  return matches;
}

}  // namespace

bool WideBaselineOptions::Check(std::string* error) const {
  const auto fail = [&](const char* message) {
    if (error != nullptr) *error = message;
    return false;
  };
  if (max_dog_keypoints < 0 || max_harris_keypoints < 0 || max_mser_keypoints < 0) {
    return fail("key-point counts must not be negative");
  }
  if (max_dog_keypoints + max_harris_keypoints + max_mser_keypoints == 0) return fail("every detector is disabled");
  if (harris_levels < 1) return fail("harris_levels must be at least 1");
  if (!(ratio > 0.0 && ratio <= 1.0)) return fail("ratio must be in (0, 1]");
  if (!(fusion_radius_px > 0.0)) return fail("fusion_radius_px must be positive");
  return true;
}

WideBaselineFeatures ExtractWideBaselineFeatures(const cv::Mat& image, const WideBaselineOptions& options) {
  CV_Assert(image.type() == CV_8UC1);
  WideBaselineFeatures features;
  const double radius = options.fusion_radius_px;
  const int grid_cols = static_cast<int>(std::ceil(image.cols / radius)) + 1;
  const int grid_rows = static_cast<int>(std::ceil(image.rows / radius)) + 1;
  std::vector<std::vector<int>> grid(static_cast<size_t>(grid_cols) * grid_rows);
  // Priority of the detectors in the fusion: DoG (best localized in scale), then Harris, then MSER.
  FuseInto(DetectDoG(image, options), radius, &features.keypoints, &grid, grid_cols);
  FuseInto(DetectMultiScaleHarris(image, options), radius, &features.keypoints, &grid, grid_cols);
  FuseInto(DetectMser(image, options), radius, &features.keypoints, &grid, grid_cols);
  if (options.upright) {
    for (cv::KeyPoint& k : features.keypoints) k.angle = 0.0f;
  } else {
    // Harris and MSER key-points carry no orientation; SIFT then describes them upright.
    for (cv::KeyPoint& k : features.keypoints) k.angle = std::max(0.0f, k.angle);
  }
  if (features.keypoints.empty()) {
    features.descriptors = cv::Mat(0, 128, CV_32F);
    return features;
  }
  cv::SIFT::create()->compute(image, features.keypoints, features.descriptors);
  // SIFT::compute may drop key-points too close to the border; the class ids travel with the key-points.
  return features;
}

std::vector<cv::DMatch> MatchWideBaseline(const WideBaselineFeatures& query, const WideBaselineFeatures& train,
                                          const WideBaselineOptions& options) {
  std::vector<cv::DMatch> matches;
  if (query.size() < 2 || train.size() < 2) return matches;
  CV_Assert(query.descriptors.type() == train.descriptors.type() &&
            query.descriptors.cols == train.descriptors.cols);
  if (query.descriptors.type() == CV_8U) return MatchBinaryDescriptors(query.descriptors, train.descriptors, options);
  CV_Assert(query.descriptors.type() == CV_32F);
  // Exhaustive nearest neighbours in both directions from ONE table of squared distances
  // |q - t|^2 = |q|^2 + |t|^2 - 2 q.t, computed blockwise as a matrix product: the same matches as a brute-force
  // matcher run twice (forward for the ratio test, backward for the cross-check) at a fraction of its time
  // (relocalization matches a frame against many key-images).
  using RowMajor = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  const cv::Mat q_mat = query.descriptors.isContinuous() ? query.descriptors : query.descriptors.clone();
  const cv::Mat t_mat = train.descriptors.isContinuous() ? train.descriptors : train.descriptors.clone();
  const Eigen::Map<const RowMajor> q(q_mat.ptr<float>(), q_mat.rows, q_mat.cols);
  const Eigen::Map<const RowMajor> t(t_mat.ptr<float>(), t_mat.rows, t_mat.cols);
  const Eigen::VectorXf q_norms = q.rowwise().squaredNorm();
  const Eigen::RowVectorXf t_norms = t.rowwise().squaredNorm().transpose();
  const int n = static_cast<int>(q.rows()), m = static_cast<int>(t.rows());
  std::vector<int> best(n, -1);
  std::vector<float> best_d(n, std::numeric_limits<float>::infinity()), second_d(n, best_d[0]);
  std::vector<int> best_query_of_train(m, -1);
  std::vector<float> best_query_d(m, std::numeric_limits<float>::infinity());
  constexpr int kBlock = 256;
  RowMajor block;
  for (int begin = 0; begin < n; begin += kBlock) {
    const int rows = std::min(kBlock, n - begin);
    block.noalias() = q.middleRows(begin, rows) * t.transpose();
    for (int r = 0; r < rows; ++r) {
      const int i = begin + r;
      for (int j = 0; j < m; ++j) {
        const float d = std::max(0.0f, q_norms[i] + t_norms[j] - 2.0f * block(r, j));
        if (d < best_d[i]) {
          second_d[i] = best_d[i];
          best_d[i] = d;
          best[i] = j;
        } else if (d < second_d[i]) {
          second_d[i] = d;
        }
        if (d < best_query_d[j]) {
          best_query_d[j] = d;
          best_query_of_train[j] = i;
        }
      }
    }
  }
  const float ratio_squared = static_cast<float>(options.ratio * options.ratio);
  for (int i = 0; i < n; ++i) {
    if (best[i] < 0 || !(best_d[i] < ratio_squared * second_d[i])) continue;  // Segvic 2009 §4.1
    if (options.cross_check && best_query_of_train[best[i]] != i) continue;
    matches.emplace_back(i, best[i], std::sqrt(best_d[i]));
  }
  return matches;
}

std::vector<cv::DMatch> MatchAlongEpipolarPlanes(const WideBaselineFeatures& query, const WideBaselineFeatures& train,
                                                 const std::vector<Eigen::Vector3d>& query_bearings,
                                                 const std::vector<Eigen::Vector3d>& train_bearings,
                                                 const Eigen::Matrix3d& essential, double max_angle,
                                                 const WideBaselineOptions& options) {
  CV_Assert(query.descriptors.type() == CV_8U && train.descriptors.type() == CV_8U &&
            query.descriptors.cols == train.descriptors.cols);
  CV_Assert(query_bearings.size() == query.size() && train_bearings.size() == train.size());
  const double max_sine = std::sin(max_angle);
  const int bytes = query.descriptors.cols;
  std::vector<cv::DMatch> best_of_train(train.size(), cv::DMatch(-1, -1, std::numeric_limits<float>::infinity()));
  for (size_t i = 0; i < query.size(); ++i) {
    if (query_bearings[i].squaredNorm() == 0.0) continue;
    // The epipolar plane of query key-point i in the train camera: normal E x_q.
    const Eigen::Vector3d normal = essential * query_bearings[i].normalized();
    if (!(normal.norm() > 0.0)) continue;
    const Eigen::Vector3d unit_normal = normal.normalized();
    int best = -1;
    int best_d = std::numeric_limits<int>::max(), second_d = std::numeric_limits<int>::max();
    const uchar* descriptor = query.descriptors.ptr<uchar>(static_cast<int>(i));
    for (size_t j = 0; j < train.size(); ++j) {
      const double length = train_bearings[j].norm();
      if (length == 0.0 || std::abs(unit_normal.dot(train_bearings[j])) > max_sine * length) continue;
      const int d = cv::hal::normHamming(descriptor, train.descriptors.ptr<uchar>(static_cast<int>(j)), bytes);
      if (d < best_d) {
        second_d = best_d;
        best_d = d;
        best = static_cast<int>(j);
      } else if (d < second_d) {
        second_d = d;
      }
    }
    if (best < 0) continue;
    // The ratio test within the band; a lone candidate passes.
    if (second_d != std::numeric_limits<int>::max() && !(best_d < options.ratio * second_d)) continue;
    if (best_d < best_of_train[best].distance) {
      best_of_train[best] = cv::DMatch(static_cast<int>(i), best, static_cast<float>(best_d));
    }
  }
  std::vector<cv::DMatch> matches;
  for (const cv::DMatch& m : best_of_train) {
    if (m.queryIdx >= 0) matches.push_back(m);
  }
  return matches;
}

}  // namespace retrace
