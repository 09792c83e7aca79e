#include "retrace/geometry/synthetic.h"

#include <algorithm>
#include <cmath>
#include <random>

namespace retrace {

bool SyntheticTwoViewOptions::Check() const {
  return num_points >= 0 && noise_px >= 0.0 && outlier_ratio >= 0.0 && outlier_ratio <= 1.0 && min_distance > 0.0 &&
         max_distance >= min_distance;
}

SyntheticTwoView GenerateTwoView(const CameraModel& camera, const Rigid3d& b_from_a,
                                 const SyntheticTwoViewOptions& options) {
  SyntheticTwoView scene;
  scene.b_from_a = b_from_a;
  if (!options.Check()) return scene;
  std::mt19937_64 rng(options.seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, options.noise_px);
  const auto random_pixel = [&]() {
    return Vector2d(u(rng) * (camera.width() - 1), u(rng) * (camera.height() - 1));
  };
  const int num_outliers = static_cast<int>(std::lround(options.outlier_ratio * options.num_points));
  // Outliers are spread over the sequence rather than grouped at the end.
  std::vector<bool> outlier_flags(options.num_points, false);
  for (int i = 0; i < num_outliers; ++i) outlier_flags[i] = true;
  std::shuffle(outlier_flags.begin(), outlier_flags.end(), rng);

  for (int i = 0; i < options.num_points; ++i) {
    for (int attempt = 0; attempt < 1000; ++attempt) {
      Vector3d ray;
      if (!camera.Unproject(random_pixel(), &ray)) continue;
      const double distance = options.min_distance + u(rng) * (options.max_distance - options.min_distance);
      const Vector3d point_a = distance * ray;
      const Vector3d point_b = b_from_a * point_a;
      Vector2d pixel_a, pixel_b;
      if (point_b.norm() < 0.5 * options.min_distance) continue;
      if (!camera.Project(point_a, &pixel_a) || !camera.Project(point_b, &pixel_b)) continue;
      if (!camera.InImage(pixel_a) || !camera.InImage(pixel_b)) continue;
      pixel_a += Vector2d(noise(rng), noise(rng));
      pixel_b = outlier_flags[i] ? random_pixel() : Vector2d(pixel_b + Vector2d(noise(rng), noise(rng)));
      Vector3d bearing_a, bearing_b;
      if (!camera.Unproject(pixel_a, &bearing_a) || !camera.Unproject(pixel_b, &bearing_b)) continue;
      scene.points_in_a.push_back(point_a);
      scene.pixels_a.push_back(pixel_a);
      scene.pixels_b.push_back(pixel_b);
      scene.bearings_a.push_back(bearing_a);
      scene.bearings_b.push_back(bearing_b);
      scene.is_outlier.push_back(outlier_flags[i]);
      break;
    }
  }
  return scene;
}

}  // namespace retrace
