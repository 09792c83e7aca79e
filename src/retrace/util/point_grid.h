#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include "retrace/util/types.h"

namespace retrace {

// Points bucketed in square cells of side `cell`: the points within k cells' side of a position lie in the
// (2k + 1)² cells around the position's own (a point's cell and the position's, clamped to the grid, differ by at
// most k in each direction), so a search within k sides visits those cells only.
class PointGrid {
 public:
  PointGrid(const std::vector<Vector2d>& points, double cell) : cell_(cell) {
    if (points.empty() || !(cell > 0.0)) return;
    origin_ = points.front();
    Vector2d far = points.front();
    for (const Vector2d& p : points) {
      origin_ = origin_.cwiseMin(p);
      far = far.cwiseMax(p);
    }
    // At most 1024 cells a side (clamping a cell index keeps the argument above; only the search grows).
    cols_ = static_cast<int>(std::min(1023.0, std::floor((far.x() - origin_.x()) / cell_))) + 1;
    rows_ = static_cast<int>(std::min(1023.0, std::floor((far.y() - origin_.y()) / cell_))) + 1;
    // Counting sort by cell: the points of cell c are indices_[starts_[c] .. starts_[c + 1]), in index order.
    starts_.assign(static_cast<size_t>(cols_) * rows_ + 1, 0);
    std::vector<int> cell_of(points.size());
    for (size_t i = 0; i < points.size(); ++i) {
      cell_of[i] = Row(points[i].y()) * cols_ + Col(points[i].x());
      ++starts_[cell_of[i] + 1];
    }
    for (size_t c = 1; c < starts_.size(); ++c) starts_[c] += starts_[c - 1];
    indices_.resize(points.size());
    std::vector<int> next(starts_.begin(), starts_.end() - 1);
    for (size_t i = 0; i < points.size(); ++i) indices_[next[cell_of[i]]++] = i;
  }

  // Calls visit(i) for every point within `cells` cells of `centre` (and some farther: the caller tests distance).
  template <typename Visit>
  void ForEachNear(const Vector2d& centre, int cells, Visit visit) const {
    if (indices_.empty()) return;
    const int col = Col(centre.x()), row = Row(centre.y());
    for (int r = std::max(0, row - cells); r <= std::min(rows_ - 1, row + cells); ++r) {
      const int first = r * cols_ + std::max(0, col - cells), last = r * cols_ + std::min(cols_ - 1, col + cells);
      for (int k = starts_[first]; k < starts_[last + 1]; ++k) visit(indices_[k]);
    }
  }

 private:
  static int Clamped(double cells, int count) {
    return static_cast<int>(std::clamp(std::floor(cells), 0.0, static_cast<double>(count - 1)));
  }
  int Col(double x) const { return Clamped((x - origin_.x()) / cell_, cols_); }
  int Row(double y) const { return Clamped((y - origin_.y()) / cell_, rows_); }

  double cell_;
  Vector2d origin_ = Vector2d::Zero();
  int cols_ = 0, rows_ = 0;
  std::vector<int> starts_;
  std::vector<size_t> indices_;
};

}  // namespace retrace
