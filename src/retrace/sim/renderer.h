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
//  - Geometric and shadow edges (adaptive supersampling, Mitchell 1987 "Generating antialiased images at low sampling
//    densities"): every pixel first gets one ray; a pixel whose 4-neighbour sees another object, another face or
//    another shadow state, and differs from it by more than `edge_contrast` grey levels, gets more samples.
//    antialiasing = 2 (the default) samples the four pixel corners and blends 1/2 centre + 1/8 each corner
//    ("quincunx", a tent filter): an edge sweeping across the pixel changes it in steps of 1/4, 1/2, 1/4 along the
//    linear ramp of the pixel integral, and corners are shared by neighbouring edge pixels (edges come in
//    two-pixel-wide bands), so an edge pixel costs about 1.5 extra rays instead of the 4 of a 2x2 grid.
//    antialiasing = n >= 3 re-renders the pixel with an n x n grid of sub-samples and averages (box filter).
//    Textures are already filtered, so flat textured areas need no extra samples.
//
// Lighting: Lambertian reflectance under a sun (directional light, shadows by occlusion rays) plus sky light that
// is stronger on upward surfaces; the sky itself has a gradient, a sun glow and a cloud layer. The sensor applies
// exposure x gain, a gamma 1/2.2 response, 8-bit quantisation and Gaussian noise. Everything is deterministic: the
// noise of pixel (x, y) comes from a hash of (noise_seed, x, y), independent of threads and tiles.
//
// Speed: the camera's rays (bearings and differentials) are unprojected once in the constructor and stored tile by
// tile; a frame only rotates them. Scratch arrays of a ray batch are per thread; nothing virtual per pixel. The
// helper threads are started once per Renderer and woken per parallel pass.

#include <cstdint>
#include <memory>
#include <vector>

#include <opencv2/core.hpp>

#include "retrace/camera/camera_model.h"
#include "retrace/sim/scene.h"
#include "retrace/util/types.h"

namespace retrace {

// Ranges of the fields (here, in SensorOptions and RenderOptions): Scenario::Check (sim/scenario.h,
// ScenarioKeyRanges).
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
};

struct RenderOptions {
  // Edge supersampling: 1 = off, 2 = quincunx (centre + the four shared pixel corners), n >= 3 = n x n grid.
  int antialiasing = 2;
  // An edge pixel is supersampled only if it differs from its neighbour across the edge by more than this many grey
  // levels (8-bit, after exposure and response, before noise): the largest error left at a seam is half of it.
  double edge_contrast = 4.0;
  // Mip-mapped anisotropic texture lookup (false: nearest level-0 bilinear, which aliases; for comparisons).
  bool filter_textures = true;
  // Sun shadows by occlusion rays.
  bool shadows = true;
  // Threads over image tiles (1 = render on the calling thread).
  int num_threads = 2;
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
  class WorkerPool;
  void RenderTile(const Frame& frame, int tile) const;
  void QuincunxEdges(const Frame& frame, const std::vector<int>& edges) const;
  void SupersampleRange(const Frame& frame, const std::vector<int>& pixels, size_t begin, size_t end) const;
  void TraceBatch(const Frame& frame, const Vector3f* directions, const Vector3f* diff_x, const Vector3f* diff_y,
                  int count, Vector3f* colors, uint32_t* keys) const;

  std::unique_ptr<CameraModel> camera_;
  RenderOptions options_;
  // Rays of the valid pixels, tile after tile (tile t: [tile_begin_[t], tile_begin_[t + 1])); per pixel its index
  // in rays_ (-1: the camera model has no ray there) and a valid flag.
  std::vector<PixelRay> rays_;
  std::vector<int> tile_begin_;
  std::vector<int> ray_of_pixel_;
  std::vector<uint8_t> valid_;
  // Per pixel, antialiasing^2 sub-sample bearings (antialiasing >= 3).
  std::vector<Vector3f> sub_bearings_;
  // (width + 1) x (height + 1) pixel corner bearings and valid flags (antialiasing = 2).
  std::vector<Vector3f> corner_bearings_;
  std::vector<uint8_t> corner_valid_;
  mutable size_t last_supersampled_ = 0;
  // Helper threads (num_threads - 1 of them, started once) and per-frame buffers kept between frames (no allocation
  // and page faults per frame). So one Renderer renders one frame at a time (Render() is not reentrant).
  std::unique_ptr<WorkerPool> pool_;
  mutable std::vector<Vector3f> color_;
  mutable std::vector<uint32_t> key_;
  mutable std::vector<float> level_;
  mutable std::vector<uint8_t> mark_;
  mutable std::vector<uint8_t> corner_needed_;
  mutable std::vector<Vector3f> corner_color_;
};

}  // namespace retrace
