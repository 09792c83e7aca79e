#pragma once

// Per-frame image preparation shared by everything that tracks or detects in one frame.
//
// A frame is converted ONCE to float, pre-smoothed with a Gaussian and reduced into a pyramid; the detector,
// the reference-aligned tracker and the prediction refinement all read the same levels. Pre-smoothing widens
// the basin of convergence of the differential alignment and suppresses aliasing and sensor noise (Segvic
// 2009, §4.2 and §6.3: "due to the presmoothing of input images ... false positive feature recognitions occur
// very rarely").
//
// Coordinates: the centre of the top-left pixel is (0, 0) at every level, and level l+1 is obtained with
// cv::pyrDown (5-tap Gaussian, then every second sample), so a point x at level 0 is x / 2^l at level l.

#include <opencv2/core.hpp>
#include <vector>

namespace retrace {

struct ImagePyramidOptions {
  // Number of levels including the full-resolution level 0. 3 levels (1, 1/2, 1/4) let the tracker follow
  // displacements of more than 10 px at 320x240 (Segvic 2009, §4.2 and §6.5).
  int num_levels = 3;
  // Standard deviation (pixels of level 0) of the Gaussian pre-smoothing; 0 disables it. Measured trade-off:
  // 1.0 gives longer tracks on KITTI at R = 6 (residuals are smaller) but biases the scale (and with it the
  // position) of the tracker more under scale changes, because the smoothing is fixed in pixels; 0.5 keeps
  // the synthetic-warp errors at a median of 0.02-0.03 px.
  double smoothing_sigma = 0.5;

  bool Check() const { return num_levels >= 1 && num_levels <= 10 && smoothing_sigma >= 0.0; }
};

// Pyramid settings for tracking in images `width` pixels wide, with pixel quantities given for images
// `reference_width` wide (Segvic 2009 works at 320x240): the pre-smoothing scales with the resolution
// (`smoothing_sigma_px` at the reference width), and there is one more level per doubling of the resolution so
// that the coarsest level sees the same motion. Teach and repeat must use the same settings, so that the tracker's
// residuals (and thus R) mean the same in both phases.
// The default pre-smoothing of teach and repeat (pixels at 320 px width): fine texture that the paper's 320x240
// images did not resolve would otherwise count as appearance change against R.
inline constexpr double kTrackingSmoothingPx = 0.7;
ImagePyramidOptions TrackingPyramidOptions(int width, int reference_width = 320,
                                           double smoothing_sigma_px = kTrackingSmoothingPx);

class ImagePyramid {
 public:
  ImagePyramid() = default;
  // `image` is single channel, CV_8U or CV_32F (grey levels 0..255 expected; float values are used as given).
  explicit ImagePyramid(const cv::Mat& image, const ImagePyramidOptions& options = {});

  // Rebuilds the pyramid from a new frame, reusing the buffers when the size did not change (no allocation
  // per frame in a steady state). Throws std::invalid_argument on an empty or multi-channel image or bad
  // options.
  void Build(const cv::Mat& image, const ImagePyramidOptions& options = {});

  int NumLevels() const { return static_cast<int>(levels_.size()); }
  // Smoothed float image (CV_32FC1, continuous) of level `level` (0 = full resolution).
  const cv::Mat& Level(int level) const { return levels_[level]; }
  int Width() const { return levels_.empty() ? 0 : levels_[0].cols; }
  int Height() const { return levels_.empty() ? 0 : levels_[0].rows; }
  bool Empty() const { return levels_.empty(); }
  const ImagePyramidOptions& Options() const { return options_; }
  // The first `num_levels` levels (at least 1) as a pyramid of their own, sharing the image data (no copy): to
  // align a feature whose position is already known to a few pixels without the coarsest levels.
  ImagePyramid FinestLevels(int num_levels) const;

 private:
  ImagePyramidOptions options_;
  cv::Mat input_float_;
  std::vector<cv::Mat> levels_;
};

}  // namespace retrace
