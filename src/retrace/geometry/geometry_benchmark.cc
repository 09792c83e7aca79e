// Benchmarks of the geometry layer: robust 5-point relative pose (150 correspondences, 30 % outliers), with and
// without a good guess (the previous frame's geometry while tracking), robust absolute pose (P3P), the two minimal
// solvers alone and σ_p.
//
//   build/src/retrace/geometry/bench_geometry_geometry_benchmark --benchmark_repetitions=5
//       --benchmark_report_aggregates_only=true

#include <random>

#include <benchmark/benchmark.h>

#include "retrace/camera/perspective_camera.h"
#include "retrace/geometry/absolute_pose.h"
#include "retrace/geometry/p3p.h"
#include "retrace/geometry/planar_pose.h"
#include "retrace/geometry/relative_pose.h"
#include "retrace/geometry/sigma_p.h"
#include "retrace/geometry/synthetic.h"

namespace retrace {
namespace {

SyntheticTwoView Scene(const Rigid3d& pose) {
  const PerspectiveCamera camera(640, 480, 500.0, 500.0, 319.5, 239.5);
  SyntheticTwoViewOptions options;
  options.num_points = 150;
  options.outlier_ratio = 0.3;
  options.noise_px = 0.5;
  options.min_distance = 3.0;
  options.max_distance = 15.0;
  return GenerateTwoView(camera, pose, options);
}

void BM_RelativePose5Point150Points30PercentOutliers(benchmark::State& state) {
  const Rigid3d pose(Eigen::AngleAxisd(0.08, Vector3d(0.1, 1.0, 0.05).normalized()).toRotationMatrix(),
                     Vector3d(0.2, 0.05, -1.0));
  const SyntheticTwoView scene = Scene(pose);
  int iterations = 0;
  for (auto _ : state) {
    const TwoViewGeometry g = EstimateRelativePose(scene.bearings_a, scene.bearings_b, 500.0);
    if (!g.success) state.SkipWithError("estimation failed");
    iterations = g.num_iterations;
    benchmark::DoNotOptimize(g.b_from_a.rotation(0, 0));
  }
  state.counters["samples"] = iterations;
}
BENCHMARK(BM_RelativePose5Point150Points30PercentOutliers)->Unit(benchmark::kMillisecond);

// The same scene with 10 % outliers, as the tracked features of repeat, estimated from a guess near the truth (the
// previous frame's geometry) with the repeat's sample floor (30 without a guess).
void BM_RelativePoseWithGuess150Points10PercentOutliers(benchmark::State& state) {
  const Rigid3d pose(Eigen::AngleAxisd(0.08, Vector3d(0.1, 1.0, 0.05).normalized()).toRotationMatrix(),
                     Vector3d(0.2, 0.05, -1.0));
  const PerspectiveCamera camera(640, 480, 500.0, 500.0, 319.5, 239.5);
  SyntheticTwoViewOptions scene_options;
  scene_options.num_points = 150;
  scene_options.outlier_ratio = 0.1;
  scene_options.min_distance = 3.0;
  scene_options.max_distance = 15.0;
  const SyntheticTwoView scene = GenerateTwoView(camera, pose, scene_options);
  const Rigid3d guess(Eigen::AngleAxisd(0.085, Vector3d(0.1, 1.0, 0.05).normalized()).toRotationMatrix(),
                      Vector3d(0.21, 0.05, -0.98));
  TwoViewOptions options;
  options.ransac.min_iterations = 30;
  const bool with_guess = state.range(0) != 0;
  int iterations = 0;
  for (auto _ : state) {
    const TwoViewGeometry g =
        EstimateRelativePose(scene.bearings_a, scene.bearings_b, 500.0, options, with_guess ? &guess : nullptr);
    if (!g.success) state.SkipWithError("estimation failed");
    iterations = g.num_iterations;
    benchmark::DoNotOptimize(g.b_from_a.rotation(0, 0));
  }
  state.counters["samples"] = iterations;
}
BENCHMARK(BM_RelativePoseWithGuess150Points10PercentOutliers)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// The minimal 5-point solver alone (essential matrices, decomposition, cheirality on the sample), on consecutive
// samples of five inliers of the scene above without outliers.
void BM_FivePointMinimalSolver(benchmark::State& state) {
  const Rigid3d pose(Eigen::AngleAxisd(0.08, Vector3d(0.1, 1.0, 0.05).normalized()).toRotationMatrix(),
                     Vector3d(0.2, 0.05, -1.0));
  const PerspectiveCamera camera(640, 480, 500.0, 500.0, 319.5, 239.5);
  SyntheticTwoViewOptions options;
  options.num_points = 150;
  options.outlier_ratio = 0.0;
  options.min_distance = 3.0;
  options.max_distance = 15.0;
  const SyntheticTwoView scene = GenerateTwoView(camera, pose, options);
  std::vector<int> sample(5);
  std::vector<Rigid3d> poses;
  int first = 0;
  size_t solutions = 0;
  for (auto _ : state) {
    for (int k = 0; k < 5; ++k) sample[k] = (first + k) % 150;
    first = (first + 5) % 150;
    poses.clear();
    SolveFivePoint(scene.bearings_a, scene.bearings_b, sample, &poses);
    solutions += poses.size();
    benchmark::DoNotOptimize(poses.data());
  }
  state.counters["poses"] = benchmark::Counter(static_cast<double>(solutions), benchmark::Counter::kAvgIterations);
}
BENCHMARK(BM_FivePointMinimalSolver)->Unit(benchmark::kMicrosecond);

// Absolute pose of the second camera from the first camera's points (the repeat's placement of the camera in an
// arc's reconstruction), 150 correspondences, 30 % outliers.
void BM_AbsolutePose150Points30PercentOutliers(benchmark::State& state) {
  const Rigid3d pose(Eigen::AngleAxisd(0.08, Vector3d(0.1, 1.0, 0.05).normalized()).toRotationMatrix(),
                     Vector3d(0.2, 0.05, -1.0));
  const SyntheticTwoView scene = Scene(pose);
  int iterations = 0;
  for (auto _ : state) {
    const AbsolutePose p = EstimateAbsolutePose(scene.points_in_a, scene.bearings_b, 500.0);
    if (!p.success) state.SkipWithError("estimation failed");
    iterations = p.num_iterations;
    benchmark::DoNotOptimize(p.cam_from_world.rotation(0, 0));
  }
  state.counters["samples"] = iterations;
}
BENCHMARK(BM_AbsolutePose150Points30PercentOutliers)->Unit(benchmark::kMicrosecond);

// The minimal P3P solver alone, on consecutive triples of the scene's points seen from the second camera.
void BM_P3PMinimalSolver(benchmark::State& state) {
  const Rigid3d pose(Eigen::AngleAxisd(0.08, Vector3d(0.1, 1.0, 0.05).normalized()).toRotationMatrix(),
                     Vector3d(0.2, 0.05, -1.0));
  const SyntheticTwoView scene = Scene(pose);
  std::vector<Rigid3d> poses;
  size_t first = 0, solutions = 0;
  for (auto _ : state) {
    const Vector3d points[3] = {scene.points_in_a[first], scene.points_in_a[first + 1], scene.points_in_a[first + 2]};
    const Vector3d bearings[3] = {scene.bearings_b[first], scene.bearings_b[first + 1], scene.bearings_b[first + 2]};
    first = (first + 3) % (scene.points_in_a.size() - 2);
    poses.clear();
    SolveP3P(points, bearings, &poses);
    solutions += poses.size();
    benchmark::DoNotOptimize(poses.data());
  }
  state.counters["poses"] = benchmark::Counter(static_cast<double>(solutions), benchmark::Counter::kAvgIterations);
}
BENCHMARK(BM_P3PMinimalSolver)->Unit(benchmark::kMicrosecond);

void BM_PlanarPose150Points30PercentOutliers(benchmark::State& state) {
  const SyntheticTwoView scene = Scene(PlanarPose(0.1, 3.0));
  for (auto _ : state) {
    const TwoViewGeometry g = EstimatePlanarRelativePose(scene.bearings_a, scene.bearings_b, 500.0);
    if (!g.success) state.SkipWithError("estimation failed");
    benchmark::DoNotOptimize(g.b_from_a.rotation(0, 0));
  }
}
BENCHMARK(BM_PlanarPose150Points30PercentOutliers)->Unit(benchmark::kMillisecond);

// σ_p of n residual vectors (sum of squares + tabulated χ² quantile).
void BM_SigmaP(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0.0, 0.5);
  std::vector<Vector2d> residuals(n);
  for (auto& r : residuals) r = Vector2d(noise(rng), noise(rng));
  for (auto _ : state) benchmark::DoNotOptimize(SigmaP(residuals));
}
BENCHMARK(BM_SigmaP)->Arg(10)->Arg(100)->Arg(1000);

// The quantile alone, from the table and beyond it (Boost.Math).
void BM_ChiSquareQuantile(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(ChiSquareQuantile2n(0.05, n));
}
BENCHMARK(BM_ChiSquareQuantile)->Arg(100)->Arg(5000);

}  // namespace
}  // namespace retrace
