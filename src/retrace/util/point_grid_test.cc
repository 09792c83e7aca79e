#include "retrace/util/point_grid.h"

#include <algorithm>
#include <random>

#include <gtest/gtest.h>

namespace retrace {
namespace {

// The points within k cells' side of a position, found by the grid, are those a scan of every point finds, for
// positions inside, at the edge of and outside the points' extent, and for points exactly k sides away.
TEST(PointGrid, FindsWhatAScanOfEveryPointFinds) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> coordinate(-50.0, 1300.0);
  std::vector<Vector2d> points;
  for (int i = 0; i < 400; ++i) points.emplace_back(coordinate(rng), 0.3 * coordinate(rng));
  const double radius = 115.0;
  points.emplace_back(600.0 + 2.0 * radius, 100.0);  // exactly two radii from the first centre below
  const PointGrid grid(points, radius * (1.0 + 1e-6));
  std::vector<Vector2d> centres = {{600.0, 100.0}, {-400.0, -90.0}, {2000.0, 500.0}, {0.0, 0.0}};
  for (int i = 0; i < 50; ++i) centres.emplace_back(coordinate(rng), 0.3 * coordinate(rng));
  int found_in_all = 0;
  for (const Vector2d& centre : centres) {
    for (int k = 1; k <= 3; ++k) {
      std::vector<size_t> scanned, searched;
      for (size_t i = 0; i < points.size(); ++i) {
        if ((points[i] - centre).norm() <= k * radius) scanned.push_back(i);
      }
      grid.ForEachNear(centre, k, [&](size_t i) {
        if ((points[i] - centre).norm() <= k * radius) searched.push_back(i);
      });
      std::sort(searched.begin(), searched.end());
      EXPECT_EQ(searched, scanned) << "centre " << centre.transpose() << ", " << k << " radii";
      found_in_all += static_cast<int>(scanned.size());
    }
  }
  EXPECT_GT(found_in_all, 1000);  // the searches were not all empty
}

TEST(PointGrid, VisitsOnlyTheCellsAroundThePosition) {
  // Points on a line 1 apart in cells of 10: within one cell's side of x = 55 lie the cells of 40-69 only.
  std::vector<Vector2d> points;
  for (int x = 0; x < 100; ++x) points.emplace_back(x, 0.0);
  const PointGrid grid(points, 10.0);
  int visited = 0;
  grid.ForEachNear(Vector2d(55.0, 0.0), 1, [&](size_t i) {
    EXPECT_GE(points[i].x(), 40.0);
    EXPECT_LT(points[i].x(), 70.0);
    ++visited;
  });
  EXPECT_EQ(visited, 30);
}

TEST(PointGrid, NoPointsVisitsNothing) {
  const PointGrid grid({}, 10.0);
  int visited = 0;
  grid.ForEachNear(Vector2d(1.0, 2.0), 3, [&](size_t) { ++visited; });
  EXPECT_EQ(visited, 0);
}

}  // namespace
}  // namespace retrace
