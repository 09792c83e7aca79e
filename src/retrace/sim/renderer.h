#pragma once

// Ray-casting renderer of a Scene through any retrace CameraModel.
//
// Each pixel's ray is the camera model's own Unproject(pixel): the images are exactly what that model (perspective
// with radial-tangential distortion, equirectangular panorama, ...) would record, so a 3D point projects with
// CameraModel::Project onto where it is drawn. Rays are traced in coherent batches per 16x16 tile with Embree's
// stream API (rtcIntersect1M / rtcOccluded1M) on `num_threads` threads.
//
// Anti-aliasing has two parts:
//  - Textures: mip-mapped anisotropic lookup (texture.h). The pixel footprint comes from ray differentials
//    (Igehy 1999, "Tracing ray differentials"): with dD the change of the ray direction to the neighbouring pixel,
//    the hit point moves by dP = t (dD - (dD.n)/(D.n) D) on the plane with normal n, and the texture gradients of
//    the triangle map dP to texture space.
//  - Geometric and shadow edges: a pixel whose neighbours see another object, another face, or another shadow state
//    is re-rendered with `antialiasing` x `antialiasing` sub-samples and averaged (adaptive supersampling).
//
// Lighting: Lambertian reflectance under a sun (directional light, shadows by occlusion rays) plus sky light that
// is stronger on upward surfaces; the sky itself has a gradient, a sun glow and a cloud layer. The sensor applies
// exposure x gain, a gamma 1/2.2 response, 8-bit quantisation and Gaussian noise. Everything is deterministic: the
// noise of pixel (x, y) comes from a hash of (noise_seed, x, y), independent of threads and tiles.

#include <cstdint>
#include <memory>
#include <vector>

#include <opencv2/core.hpp>

#include "retrace/camera/camera_model.h"
#include "retrace/sim/scene.h"
#include "retrace/util/types.h"

namespace retrace {

struct Lighting {
  // Compass direction of the sun in degrees, clockwise from north (+Y of the town frame); east (+X) = 90.
  double sun_azimuth_deg = 160.0;
  // Height of the sun above the horizon in degrees (<= 0: no direct sunlight).
  double sun_elevation_deg = 55.0;
  // Irradiance of the sun on a surface facing it (relative units; reflectance x irradiance = radiance).
  double sun_irradiance = 1.5;
  // Irradiance of the sky on an upward surface (vertical ones get 75% of it).
  double sky_irradiance = 0.5;

  // Unit vector towards the sun in the town frame (X east, Y north, Z up).
  Vector3d SunDirection() const;
  bool Check() const;
};

struct SensorOptions {
  // Multiplies the scene radiance before the response curve (exposure time x aperture).
  double exposure = 0.75;
  // Multiplies the signal after exposure (analogue gain; noise is added after it).
  double gain = 1.0;
  // Standard deviation of Gaussian noise added to the 8-bit values (grey levels).
  double noise_sigma = 1.0;
  // Colour (CV_8UC3, BGR) instead of grey (CV_8UC1) images.
  bool color = false;

  bool Check() const;
};

struct RenderOptions {
  // Sub-samples per axis for pixels on geometric and shadow edges (1 = no edge supersampling).
  int antialiasing = 2;
  // Mip-mapped anisotropic texture lookup (false: nearest level-0 bilinear, which aliases; for comparisons).
  bool filter_textures = true;
  // Sun shadows by occlusion rays.
  bool shadows = true;
  // Threads over image tiles (1 = render on the calling thread).
  int num_threads = 2;

  bool Check() const;
};

class Renderer {
 public:
  // Precomputes the ray (and sub-sample rays) of every pixel of `camera`, which is copied.
  Renderer(const CameraModel& camera, const RenderOptions& options);
  ~Renderer();

  const CameraModel& camera() const { return *camera_; }
  const RenderOptions& options() const { return options_; }

  // Renders `scene` at its current time (Scene::SetTime) seen by a camera at `town_from_cam` (camera frame x right,
  // y down, z forward). `noise_seed` selects the sensor noise pattern (e.g. a hash of seed and frame index).
  cv::Mat Render(const Scene& scene, const Rigid3d& town_from_cam, const Lighting& lighting,
                 const SensorOptions& sensor, uint64_t noise_seed) const;

  // Number of pixels re-rendered with sub-samples in the last Render() (for tests and statistics).
  size_t last_supersampled_pixels() const { return last_supersampled_; }

 private:
  struct PixelRay;
  struct Frame;
  void RenderTile(const Frame& frame, int tile) const;
  void SupersampleRange(const Frame& frame, const std::vector<int>& pixels, size_t begin, size_t end) const;
  void TraceBatch(const Frame& frame, const Vector3f* directions, const Vector3f* diff_x, const Vector3f* diff_y,
                  int count, Vector3f* colors, uint32_t* keys) const;

  std::unique_ptr<CameraModel> camera_;
  RenderOptions options_;
  // Per pixel: bearing (camera frame), differentials to the right and lower neighbours; valid flag.
  std::vector<Vector3f> bearings_, diff_x_, diff_y_;
  std::vector<uint8_t> valid_;
  // Per pixel, antialiasing^2 sub-sample bearings.
  std::vector<Vector3f> sub_bearings_;
  mutable size_t last_supersampled_ = 0;
};

}  // namespace retrace
