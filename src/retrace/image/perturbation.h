#pragma once

// Photometric and geometric perturbations of camera images, for pseudo-repeat evaluation on single-pass real data
// (design §9: teach on even frames, repeat on odd frames with changed brightness/contrast/gamma, moving occluders,
// dropped frames, noise and blur). Everything is deterministic given the options (including `seed`) and the frame
// index, so an experiment can be reproduced exactly.
//
// For an 8-bit gray image with values v in [0, 1] (= level / 255) the perturbed image is, in this order:
//   1. occluder    a rectangle pasted into the scene (flat or textured) on frames [first, last], moving across the
//                  image from the left edge to the right edge;
//   2. photometric v' = brightness * v^gamma, then v'' = 0.5 + contrast * (v' - 0.5), clamped to [0, 1]
//                  (a change of exposure/illumination and of camera response);
//   3. blur        Gaussian, standard deviation `blur_sigma` pixels (defocus / motion);
//   4. noise       additive Gaussian, standard deviation `noise_sigma` grey levels (sensor noise), then rounding
//                  and saturation to [0, 255].

#include <cstdint>
#include <string>

#include <opencv2/core.hpp>

namespace retrace {

struct PerturbationOptions {
  // Multiplicative gain a applied after the gamma curve; 1 = unchanged, 0.6 = 40% darker. Must be >= 0.
  double brightness = 1.0;
  // Exponent g of v^g; 1 = unchanged, > 1 darkens mid-tones, < 1 brightens them. Must be > 0.
  double gamma = 1.0;
  // Contrast factor about mid-grey; 1 = unchanged, 0.5 = half the contrast. Must be >= 0.
  double contrast = 1.0;
  // Standard deviation of additive Gaussian noise in grey levels; 0 = none. Must be >= 0.
  double noise_sigma = 0.0;
  // Standard deviation of a Gaussian blur in pixels; 0 = none. Must be >= 0.
  double blur_sigma = 0.0;
  // Fraction of the image area covered by the occluder (a rectangle with the image's aspect ratio, sides scaled by
  // sqrt(fraction)); 0 = no occluder. Must be in [0, 1).
  double occluder_fraction = 0.0;
  // First and last (inclusive) frame index showing the occluder; it moves linearly from the left edge (first frame)
  // to the right edge (last frame). Default: none (last < first).
  int64_t occluder_first_frame = 0;
  int64_t occluder_last_frame = -1;
  // Textured occluder (random grey blocks, like a passing vehicle or pedestrian) or a flat one of `occluder_gray`.
  bool occluder_textured = true;
  // Grey level of a flat occluder, 0..255.
  int occluder_gray = 0;
  // Seed of the noise, of the occluder's texture and of its vertical position.
  uint64_t seed = 0;

  // True if the options are valid; otherwise `error` (if given) says which field is wrong.
  bool Check(std::string* error = nullptr) const;
  // True when no perturbation is requested (the image passes unchanged).
  bool IsIdentity() const;
};

// The occluder's rectangle in frame `frame_index` of an image of `size`, or an empty rectangle when the frame shows
// no occluder. The rectangle lies entirely inside the image.
cv::Rect OccluderRect(cv::Size size, int64_t frame_index, const PerturbationOptions& options);

// Applies the perturbations to an 8-bit gray image (other images are converted with ToGray8 first) and returns an
// 8-bit gray image. `options` must pass Check().
cv::Mat PerturbImage(const cv::Mat& image, int64_t frame_index, const PerturbationOptions& options);

}  // namespace retrace
