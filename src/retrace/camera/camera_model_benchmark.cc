// Speed of pixel <-> ray conversions, which tracking and geometry call for every feature of every frame.
//   build/src/retrace/camera/bench_camera_camera_model --benchmark_repetitions=5 --benchmark_report_aggregates_only=true

#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include "retrace/camera/perspective_camera.h"
#include "retrace/camera/unified_camera.h"

namespace retrace {
namespace {

PerspectiveCamera EurocCamera() {
  LensDistortion d;
  d.k1 = -0.28340811;
  d.k2 = 0.07395907;
  d.p1 = 0.00019359;
  d.p2 = 1.76187114e-05;
  return PerspectiveCamera(752, 480, 458.654, 457.296, 367.215, 248.375, 0.0, d);
}

UnifiedCamera MeiCamera() {  // retrace calibrate on omni_calib/catadioptric_Mei
  LensDistortion d;
  d.k1 = -0.050258;
  d.k2 = 0.00324332;
  d.p1 = 0.000731;
  d.p2 = -0.000365138;
  return UnifiedCamera(1280, 1024, 1.033463, 301.764, 301.974, 643.878, 520.915, 0.0, d);
}

std::vector<Vector2d> RandomPixels(const CameraModel& camera) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Vector2d> pixels(1024);
  for (Vector2d& p : pixels) p = Vector2d(u(rng) * (camera.width() - 1), u(rng) * (camera.height() - 1));
  return pixels;
}

void Unproject(benchmark::State& state, const CameraModel& camera) {
  const std::vector<Vector2d> pixels = RandomPixels(camera);
  size_t i = 0;
  Vector3d bearing;
  for (auto _ : state) {
    benchmark::DoNotOptimize(camera.Unproject(pixels[i++ & 1023], &bearing));
    benchmark::DoNotOptimize(bearing);
  }
}

void Project(benchmark::State& state, const CameraModel& camera) {
  std::vector<Vector3d> points;
  for (const Vector2d& p : RandomPixels(camera)) {
    Vector3d bearing;
    if (camera.Unproject(p, &bearing)) points.push_back(2.0 * bearing);
  }
  size_t i = 0;
  Vector2d pixel;
  for (auto _ : state) {
    benchmark::DoNotOptimize(camera.Project(points[i++ % points.size()], &pixel));
    benchmark::DoNotOptimize(pixel);
  }
}

void BM_PerspectiveUnproject(benchmark::State& state) { Unproject(state, EurocCamera()); }
void BM_PerspectiveProject(benchmark::State& state) { Project(state, EurocCamera()); }
void BM_UnifiedUnproject(benchmark::State& state) { Unproject(state, MeiCamera()); }
void BM_UnifiedProject(benchmark::State& state) { Project(state, MeiCamera()); }
BENCHMARK(BM_PerspectiveUnproject);
BENCHMARK(BM_PerspectiveProject);
BENCHMARK(BM_UnifiedUnproject);
BENCHMARK(BM_UnifiedProject);

}  // namespace
}  // namespace retrace
