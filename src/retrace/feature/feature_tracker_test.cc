#include "retrace/feature/feature_tracker.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "retrace/feature/corner_detector.h"
#include "retrace/feature/synthetic_texture.h"
#include "retrace/util/testing.h"

namespace retrace {
namespace {

// A known warp of a whole image: x_new = centre + scale (x - centre) + translation, grey_new = gain grey + bias.
struct ImageWarp {
  Vector2d centre = Vector2d::Zero();
  Vector2d translation = Vector2d::Zero();
  double scale = 1.0;
  double gain = 1.0;
  double bias = 0.0;

  Vector2d Apply(const Vector2d& x) const { return centre + scale * (x - centre) + translation; }
};

// Keys cubic convolution kernel (a = -0.5), support [-2, 2].
double Cubic(double x) {
  x = std::abs(x);
  if (x < 1.0) return (1.5 * x - 2.5) * x * x + 1.0;
  if (x < 2.0) return ((-0.5 * x + 2.5) * x - 4.0) * x + 2.0;
  return 0.0;
}

// Renders `source` (CV_32F) under `warp` with separable cubic interpolation in double precision (cv::warpAffine
// quantises positions to 1/32 px, too coarse for a 0.1 px test), then quantises to 8 bits like a camera.
cv::Mat WarpImage(const cv::Mat& source, const ImageWarp& warp) {
  const int w = source.cols, h = source.rows;
  // x_old = c + (x_new - c - t) / s, separately in x and y.
  auto weights = [&](int n_new, int n_old, double c, double t, std::vector<int>* first, std::vector<double>* wts) {
    first->resize(n_new);
    wts->resize(4 * n_new);
    for (int i = 0; i < n_new; ++i) {
      const double x = c + (i - c - t) / warp.scale;
      const int f = static_cast<int>(std::floor(x)) - 1;
      (*first)[i] = f;
      for (int k = 0; k < 4; ++k) (*wts)[4 * i + k] = Cubic(x - (f + k));
    }
  };
  std::vector<int> fx, fy;
  std::vector<double> wx, wy;
  weights(w, w, warp.centre.x(), warp.translation.x(), &fx, &wx);
  weights(h, h, warp.centre.y(), warp.translation.y(), &fy, &wy);
  auto at = [&](int y, int x) {
    return static_cast<double>(source.at<float>(std::clamp(y, 0, h - 1), std::clamp(x, 0, w - 1)));
  };
  cv::Mat horizontal(h, w, CV_64F);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      double v = 0.0;
      for (int k = 0; k < 4; ++k) v += wx[4 * x + k] * at(y, fx[x] + k);
      horizontal.at<double>(y, x) = v;
    }
  }
  cv::Mat warped(h, w, CV_64F);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      double v = 0.0;
      for (int k = 0; k < 4; ++k) v += wy[4 * y + k] * horizontal.at<double>(std::clamp(fy[y] + k, 0, h - 1), x);
      warped.at<double>(y, x) = v;
    }
  }
  cv::Mat quantised;
  warped.convertTo(quantised, CV_8U, warp.gain, warp.bias);
  return quantised;
}

cv::Mat Quantise(const cv::Mat& source) {
  cv::Mat out;
  source.convertTo(out, CV_8U);
  return out;
}

// A KITTI frame (a 480x320 crop of its centre) with its grey levels mapped linearly into [50, 150] (no clipping
// under gain 0.6..1.5 and bias +-30) and softened with a Gaussian of 1 px (so that cubic interpolation of the warp
// is accurate to well below 0.1 px).
cv::Mat LoadKittiFrameOrEmpty() {
  const std::filesystem::path path = testing::SharedDataPath("kitti07/image_0/000000.png");
  if (path.empty()) return cv::Mat();
  cv::Mat image = cv::imread(path.string(), cv::IMREAD_GRAYSCALE);
  if (image.empty()) return cv::Mat();
  cv::Mat mapped;
  image(cv::Rect((image.cols - 480) / 2, (image.rows - 320) / 2, 480, 320)).convertTo(mapped, CV_32F, 100.0 / 255.0, 50.0);
  cv::GaussianBlur(mapped, mapped, cv::Size(0, 0), 1.0);
  return mapped;
}

using WarpRenderer = std::function<cv::Mat(const ImageWarp&)>;

struct WarpErrors {
  std::vector<double> position;
  std::vector<double> scale_relative;
  std::vector<double> gain_relative;
  std::vector<double> centre_position;
  std::vector<double> centre_scale;
  int centre_cases = 0;
  int centre_tracked = 0;
};

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * (v.size() - 1) + 0.5))];
}

// Synthetic warps of `source`: each case warps the image about one detected corner (so that the corner's true
// motion is exactly the tracker's warp model) and tracks that corner and its neighbours from their old positions
// with the default options (no prediction).
WarpErrors RunSyntheticWarps(const WarpRenderer& render, int num_cases, uint64_t seed) {
  const ImagePyramid reference_pyramid(render(ImageWarp()));
  CornerDetectorOptions detector;
  detector.max_corners = 150;
  detector.min_distance = 12.0;
  detector.border = 40;
  const std::vector<Corner> corners = DetectCorners(reference_pyramid, detector);
  EXPECT_GE(corners.size(), 30u);
  std::vector<ReferencePatch> references(corners.size());
  for (size_t i = 0; i < corners.size(); ++i) references[i].Create(reference_pyramid, corners[i].position);

  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  WarpErrors errors;
  const AlignmentOptions options;
  for (int c = 0; c < num_cases; ++c) {
    ImageWarp warp;
    // The first cases are the corners of the parameter box, the rest are random inside it.
    if (c < 8) {
      const double angle = c * CV_PI / 4.0;
      warp.translation = 15.0 * Vector2d(std::cos(angle), std::sin(angle));
      warp.scale = (c % 2 == 0) ? 0.8 : 1.25;
      warp.gain = ((c / 2) % 2 == 0) ? 0.6 : 1.5;
      warp.bias = ((c / 4) % 2 == 0) ? -30.0 : 30.0;
    } else {
      const double angle = 2.0 * CV_PI * unit(rng), radius = 15.0 * std::sqrt(unit(rng));
      warp.translation = radius * Vector2d(std::cos(angle), std::sin(angle));
      warp.scale = 0.8 * std::pow(1.25 / 0.8, unit(rng));
      warp.gain = 0.6 + 0.9 * unit(rng);
      warp.bias = -30.0 + 60.0 * unit(rng);
    }
    const size_t centre_index = static_cast<size_t>(unit(rng) * corners.size()) % corners.size();
    warp.centre = corners[centre_index].position;
    const ImagePyramid pyramid(render(warp));
    for (size_t i = 0; i < corners.size(); ++i) {
      // The corner itself and neighbours whose extra displacement from the scale is small.
      const Vector2d x = corners[i].position;
      if (i != centre_index && std::abs(warp.scale - 1.0) * (x - warp.centre).norm() > 3.0) continue;
      if (!references[i].Valid()) continue;
      WarpState initial;
      initial.position = x;
      const AlignmentResult result = AlignToReference(pyramid, references[i], initial, options);
      const Vector2d truth = warp.Apply(x);
      if (i == centre_index) ++errors.centre_cases;
      if (!result.ok()) {
        if (i == centre_index) ADD_FAILURE() << "case " << c << " corner " << i << " at " << x.transpose() << ": "
                      << TrackStatusName(result.status) << " residual " << result.residual << " t "
                      << warp.translation.transpose() << " s " << warp.scale << " g " << warp.gain << " b "
                      << warp.bias;
        continue;
      }
      if (i == centre_index) ++errors.centre_tracked;
      errors.position.push_back((result.warp.position - truth).norm());
      errors.scale_relative.push_back(std::abs(result.warp.scale / warp.scale - 1.0));
      errors.gain_relative.push_back(std::abs(result.warp.gain * warp.gain - 1.0));
      if (i == centre_index) {
        errors.centre_position.push_back(errors.position.back());
        errors.centre_scale.push_back(errors.scale_relative.back());
        EXPECT_LT(errors.position.back(), 0.1) << "case " << c << " corner " << i << " t "
                                               << warp.translation.transpose() << " s " << warp.scale;
        EXPECT_LT(errors.scale_relative.back(), 0.01) << "case " << c << " corner " << i << " s " << warp.scale;
      }
    }
  }
  std::printf("  %zu centre corners: position error median %.4f / max %.4f px; scale error median %.4f%% / max "
              "%.4f%%\n",
              errors.centre_position.size(), Percentile(errors.centre_position, 0.5),
              Percentile(errors.centre_position, 1.0), 100 * Percentile(errors.centre_scale, 0.5),
              100 * Percentile(errors.centre_scale, 1.0));
  std::printf("  %zu alignments: position error median %.4f / 95%% %.4f / max %.4f px; scale error median %.4f%% / "
              "max %.4f%%; gain error median %.4f%%\n",
              errors.position.size(), Percentile(errors.position, 0.5), Percentile(errors.position, 0.95),
              Percentile(errors.position, 1.0), 100 * Percentile(errors.scale_relative, 0.5),
              100 * Percentile(errors.scale_relative, 1.0), 100 * Percentile(errors.gain_relative, 0.5));
  return errors;
}

TEST(FeatureTracker, RecoversSyntheticWarpsOfGeneratedTexture) {
  SyntheticTextureOptions options;
  options.width = 320;
  options.height = 240;
  options.num_shapes = 250;
  const SyntheticTexture texture(options);
  // Exact rendering of the warped texture: texture point X at c + s (X - c) + t.
  const WarpRenderer render = [&](const ImageWarp& warp) {
    return Quantise(texture.Render(320, 240, warp.scale, warp.centre * (1.0 - warp.scale) + warp.translation,
                                   warp.gain, warp.bias));
  };
  const WarpErrors errors = RunSyntheticWarps(render, 60, 7);
  EXPECT_EQ(errors.centre_tracked, errors.centre_cases);
  EXPECT_GE(errors.position.size(), 60u);
}

TEST(FeatureTracker, RecoversSyntheticWarpsOfKittiFrame) {
  const cv::Mat kitti = LoadKittiFrameOrEmpty();
  if (kitti.empty()) GTEST_SKIP() << "kitti07 not found; skipping";
  const WarpRenderer render = [&](const ImageWarp& warp) { return WarpImage(kitti, warp); };
  const WarpErrors errors = RunSyntheticWarps(render, 60, 11);
  EXPECT_EQ(errors.centre_tracked, errors.centre_cases);
  EXPECT_GE(errors.position.size(), 60u);
}

}  // namespace
}  // namespace retrace
