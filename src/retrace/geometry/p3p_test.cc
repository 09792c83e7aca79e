#include "retrace/geometry/p3p.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace retrace {
namespace {

struct Case {
  Rigid3d cam_from_world;
  Vector3d points[3];
  Vector3d bearings[3];
};

// A random pose (any rotation, translation up to 10) and three points at distances 1-30 along random directions from
// the camera: within 45 deg of the optical axis, or anywhere on the sphere (an omnidirectional camera).
Case RandomCase(std::mt19937_64* rng, bool omnidirectional) {
  std::normal_distribution<double> gaussian(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  Case c;
  const Vector3d axis = Vector3d(gaussian(*rng), gaussian(*rng), gaussian(*rng)).normalized();
  c.cam_from_world.rotation = Eigen::AngleAxisd(M_PI * uniform(*rng), axis).toRotationMatrix();
  c.cam_from_world.translation = 10.0 * Vector3d(gaussian(*rng), gaussian(*rng), gaussian(*rng)) / 3.0;
  for (int i = 0; i < 3; ++i) {
    Vector3d direction;
    do {
      direction = Vector3d(gaussian(*rng), gaussian(*rng), gaussian(*rng)).normalized();
    } while (!omnidirectional && direction.z() < std::cos(M_PI / 4.0));
    const Vector3d in_camera = (1.0 + 29.0 * uniform(*rng)) * direction;
    c.bearings[i] = direction;
    c.points[i] = c.cam_from_world.rotation.transpose() * (in_camera - c.cam_from_world.translation);
  }
  return c;
}

double PoseDistance(const Rigid3d& a, const Rigid3d& b) {
  return (a.rotation - b.rotation).norm() + (a.translation - b.translation).norm() / (1.0 + b.translation.norm());
}

// Known answers: the true pose is among the solutions, every solution is a rotation.
void RunKnownAnswers(bool omnidirectional, const char* name) {
  std::mt19937_64 rng(omnidirectional ? 2 : 1);
  constexpr int kCases = 2000;
  int found = 0, total_solutions = 0;
  std::vector<double> errors;
  for (int k = 0; k < kCases; ++k) {
    const Case c = RandomCase(&rng, omnidirectional);
    std::vector<Rigid3d> poses;
    SolveP3P(c.points, c.bearings, &poses);
    EXPECT_LE(poses.size(), 4u);
    total_solutions += static_cast<int>(poses.size());
    double best = 1e9;
    for (const Rigid3d& pose : poses) {
      EXPECT_LT((pose.rotation.transpose() * pose.rotation - Matrix3d::Identity()).norm(), 1e-9);
      EXPECT_NEAR(pose.rotation.determinant(), 1.0, 1e-9);
      // Roots that are real see the points along their bearings; the real parts of complex roots are returned too
      // (scored by the robust loop), so only the true pose is checked for that.
      best = std::min(best, PoseDistance(pose, c.cam_from_world));
    }
    errors.push_back(best);
    found += best < 1e-6;
  }
  std::sort(errors.begin(), errors.end());
  std::printf("  %s: true pose found in %d of %d cases (%.2f solutions each), closest: median %.1e, 99th %.1e\n",
              name, found, kCases, static_cast<double>(total_solutions) / kCases, errors[kCases / 2],
              errors[kCases * 99 / 100]);
  // Near-degenerate random triangles (on the danger cylinder) lose accuracy; all but a few are exact.
  EXPECT_GE(found, kCases * 995 / 1000);
  EXPECT_LT(errors[kCases / 2], 1e-10);
}

TEST(P3P, FindsTheTruePoseOfPerspectiveCases) { RunKnownAnswers(false, "perspective"); }

TEST(P3P, FindsTheTruePoseOfOmnidirectionalCases) { RunKnownAnswers(true, "omnidirectional"); }

TEST(P3P, HandComputedCase) {
  // Camera at the world origin looking along z; the points (1, 0, 5), (0, 1, 5), (-1, -1, 4) seen along their
  // directions: the identity is a solution.
  const Vector3d points[3] = {Vector3d(1, 0, 5), Vector3d(0, 1, 5), Vector3d(-1, -1, 4)};
  const Vector3d bearings[3] = {points[0].normalized(), points[1].normalized(), points[2].normalized()};
  std::vector<Rigid3d> poses;
  SolveP3P(points, bearings, &poses);
  double best = 1e9;
  for (const Rigid3d& pose : poses) best = std::min(best, PoseDistance(pose, Rigid3d(Matrix3d::Identity(),
                                                                                       Vector3d::Zero())));
  EXPECT_LT(best, 1e-10);
}

TEST(P3P, DegenerateTriplesGiveNothing) {
  const Vector3d bearings[3] = {Vector3d(0, 0, 1), Vector3d(0.1, 0, 1).normalized(), Vector3d(0, 0.1, 1).normalized()};
  const Vector3d collinear[3] = {Vector3d(0, 0, 5), Vector3d(1, 0, 5), Vector3d(2, 0, 5)};
  std::vector<Rigid3d> poses;
  SolveP3P(collinear, bearings, &poses);
  EXPECT_TRUE(poses.empty());
  const Vector3d coincident[3] = {Vector3d(0, 0, 5), Vector3d(0, 0, 5), Vector3d(2, 0, 5)};
  SolveP3P(coincident, bearings, &poses);
  EXPECT_TRUE(poses.empty());
  const Vector3d not_finite[3] = {Vector3d(0, 0, 5), Vector3d(std::nan(""), 0, 5), Vector3d(2, 0, 5)};
  SolveP3P(not_finite, bearings, &poses);
  EXPECT_TRUE(poses.empty());
}

}  // namespace
}  // namespace retrace
