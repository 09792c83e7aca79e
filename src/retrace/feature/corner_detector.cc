#include "retrace/feature/corner_detector.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace retrace {
namespace {

// Uniform grid over the image that answers "is there an accepted point within min_distance?" in O(1).
class DistanceGrid {
 public:
  DistanceGrid(int width, int height, double min_distance)
      : min_distance_sq_(min_distance * min_distance), cell_(std::max(1.0, min_distance)) {
    cols_ = static_cast<int>(std::ceil(width / cell_)) + 1;
    rows_ = static_cast<int>(std::ceil(height / cell_)) + 1;
    cells_.resize(static_cast<size_t>(cols_) * rows_);
  }

  bool IsFree(const Vector2d& p) const {
    if (min_distance_sq_ <= 0.0) return true;
    const int cx = CellX(p.x()), cy = CellY(p.y());
    for (int y = std::max(0, cy - 1); y <= std::min(rows_ - 1, cy + 1); ++y) {
      for (int x = std::max(0, cx - 1); x <= std::min(cols_ - 1, cx + 1); ++x) {
        for (const Vector2d& q : cells_[static_cast<size_t>(y) * cols_ + x]) {
          if ((p - q).squaredNorm() < min_distance_sq_) return false;
        }
      }
    }
    return true;
  }

  void Add(const Vector2d& p) {
    cells_[static_cast<size_t>(CellY(p.y())) * cols_ + CellX(p.x())].push_back(p);
  }

 private:
  int CellX(double x) const { return std::clamp(static_cast<int>(x / cell_), 0, cols_ - 1); }
  int CellY(double y) const { return std::clamp(static_cast<int>(y / cell_), 0, rows_ - 1); }

  double min_distance_sq_;
  double cell_;
  int cols_ = 0, rows_ = 0;
  std::vector<std::vector<Vector2d>> cells_;
};

}  // namespace

std::vector<Corner> DetectCorners(const ImagePyramid& pyramid, const CornerDetectorOptions& options,
                                  const cv::Mat& mask, const std::vector<Vector2d>& existing) {
  if (!options.Check()) throw std::invalid_argument("DetectCorners: invalid options");
  if (pyramid.Empty()) return {};
  if (!mask.empty() &&
      (mask.type() != CV_8UC1 || mask.cols != pyramid.Width() || mask.rows != pyramid.Height())) {
    throw std::invalid_argument("DetectCorners: mask must be CV_8UC1 of the image size");
  }
  const int width = pyramid.Width(), height = pyramid.Height();
  const int num_scales = std::min(options.num_scales, pyramid.NumLevels());

  std::vector<Corner> candidates;
  cv::Mat score, dilated;
  for (int level = 0; level < num_scales; ++level) {
    const cv::Mat& image = pyramid.Level(level);
    if (image.cols < options.block_size + 2 || image.rows < options.block_size + 2) break;
    if (options.use_harris) {
      cv::cornerHarris(image, score, options.block_size, 3, options.harris_k, cv::BORDER_REFLECT_101);
    } else {
      cv::cornerMinEigenVal(image, score, options.block_size, 3, cv::BORDER_REFLECT_101);
    }
    double max_score = 0.0;
    cv::minMaxLoc(score, nullptr, &max_score);
    if (!(max_score > 0.0)) continue;
    const float threshold = static_cast<float>(options.quality_level * max_score);
    cv::dilate(score, dilated, cv::Mat());  // 3x3 maximum: non-maximum suppression
    const double to_level0 = std::ldexp(1.0, level);
    for (int y = 1; y + 1 < score.rows; ++y) {
      const float* s = score.ptr<float>(y);
      const float* d = dilated.ptr<float>(y);
      for (int x = 1; x + 1 < score.cols; ++x) {
        if (s[x] < threshold || s[x] < d[x]) continue;
        const Vector2d p(x * to_level0, y * to_level0);
        if (p.x() < options.border || p.y() < options.border || p.x() > width - 1 - options.border ||
            p.y() > height - 1 - options.border) {
          continue;
        }
        if (!mask.empty() && mask.at<uint8_t>(static_cast<int>(std::lround(p.y())),
                                              static_cast<int>(std::lround(p.x()))) == 0) {
          continue;
        }
        candidates.push_back({p, s[x] / max_score, level});
      }
    }
  }
  // Strongest first; at equal relative score, the finer level (better localised) first.
  std::stable_sort(candidates.begin(), candidates.end(), [](const Corner& a, const Corner& b) {
    return a.score != b.score ? a.score > b.score : a.level < b.level;
  });

  DistanceGrid grid(width, height, options.min_distance);
  for (const Vector2d& p : existing) grid.Add(p);
  std::vector<Corner> corners;
  for (const Corner& c : candidates) {
    if (options.max_corners > 0 && static_cast<int>(corners.size()) >= options.max_corners) break;
    if (!grid.IsFree(c.position)) continue;
    grid.Add(c.position);
    corners.push_back(c);
  }
  return corners;
}

}  // namespace retrace
