#include "retrace/feature/feature_tracker.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <vector>

#include "retrace/feature/corner_detector.h"
#include "retrace/feature/synthetic_texture.h"
#include "retrace/util/testing.h"

namespace retrace {
namespace {

// A known warp of a whole image: x_new = centre + scale (x - centre) + translation, grey_new = gain grey +
// bias.
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

// Renders `source` (CV_32F) under `warp` with separable cubic interpolation in double precision
// (cv::warpAffine quantises positions to 1/32 px, too coarse for a 0.1 px test), then quantises to 8 bits
// like a camera.
cv::Mat WarpImage(const cv::Mat& source, const ImageWarp& warp) {
  const int w = source.cols, h = source.rows;
  // x_old = c + (x_new - c - t) / s, separately in x and y.
  auto weights = [&](int n_new, int n_old, double c, double t, std::vector<int>* first,
                     std::vector<double>* wts) {
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
      for (int k = 0; k < 4; ++k)
        v += wy[4 * y + k] * horizontal.at<double>(std::clamp(fy[y] + k, 0, h - 1), x);
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

// A KITTI frame (a 480x320 crop of its centre) with its grey levels mapped linearly into [50, 150] (no
// clipping under gain 0.6..1.5 and bias +-30) and softened with a Gaussian of 1 px (so that cubic
// interpolation of the warp is accurate to well below 0.1 px).
cv::Mat LoadKittiFrameOrEmpty() {
  const std::filesystem::path path = testing::SharedDataPath("kitti07/image_0/000000.png");
  if (path.empty()) return cv::Mat();
  cv::Mat image = cv::imread(path.string(), cv::IMREAD_GRAYSCALE);
  if (image.empty()) return cv::Mat();
  cv::Mat mapped;
  image(cv::Rect((image.cols - 480) / 2, (image.rows - 320) / 2, 480, 320))
      .convertTo(mapped, CV_32F, 100.0 / 255.0, 50.0);
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
  int centre_within = 0;  // centre corners with position error < 0.1 px and scale error < 1 %
  int centre_tracked = 0;
};

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * (v.size() - 1) + 0.5))];
}

// Synthetic warps of `source`: each case warps the image about one detected corner (so that the corner's true
// motion is exactly the tracker's warp model) and tracks that corner and its neighbours from their old
// positions with the default options (no prediction).
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
        if (i == centre_index)
          std::printf("  lost: case %d corner %zu: %s, residual %.2f, t (%.1f, %.1f) s %.3f g %.2f b %.1f\n",
                      c, i, TrackStatusName(result.status).c_str(), result.residual, warp.translation.x(),
                      warp.translation.y(), warp.scale, warp.gain, warp.bias);
        continue;
      }
      if (i == centre_index) ++errors.centre_tracked;
      errors.position.push_back((result.warp.position - truth).norm());
      errors.scale_relative.push_back(std::abs(result.warp.scale / warp.scale - 1.0));
      errors.gain_relative.push_back(std::abs(result.warp.gain * warp.gain - 1.0));
      if (i == centre_index) {
        errors.centre_position.push_back(errors.position.back());
        errors.centre_scale.push_back(errors.scale_relative.back());
        const bool within = errors.position.back() < 0.1 && errors.scale_relative.back() < 0.01;
        errors.centre_within += within;
        if (!within) {
          std::printf(
              "  outside 0.1 px / 1 %%: case %d t (%.1f, %.1f) s %.3f g %.2f b %.1f: position error %.3f px, "
              "scale error %.2f %%\n",
              c, warp.translation.x(), warp.translation.y(), warp.scale, warp.gain, warp.bias,
              errors.position.back(), 100 * errors.scale_relative.back());
        }
      }
    }
  }
  std::printf(
      "  %zu centre corners: position error median %.4f / max %.4f px; scale error median %.4f%% / max "
      "%.4f%%\n",
      errors.centre_position.size(), Percentile(errors.centre_position, 0.5),
      Percentile(errors.centre_position, 1.0), 100 * Percentile(errors.centre_scale, 0.5),
      100 * Percentile(errors.centre_scale, 1.0));
  std::printf(
      "  %zu alignments: position error median %.4f / 95%% %.4f / max %.4f px; scale error median %.4f%% / "
      "max %.4f%%; gain error median %.4f%%\n",
      errors.position.size(), Percentile(errors.position, 0.5), Percentile(errors.position, 0.95),
      Percentile(errors.position, 1.0), 100 * Percentile(errors.scale_relative, 0.5),
      100 * Percentile(errors.scale_relative, 1.0), 100 * Percentile(errors.gain_relative, 0.5));
  return errors;
}

// Target of issue 3, per corner: every tracked case corner (the corner the warp is centred on, so that its
// motion is exactly the tracker's warp model) has a position error < 0.1 px and a scale error < 1 %, and at
// least 90 % of the case corners are tracked. The scale of a 15x15 window around a corner is weakly observable
// (a corner is self-similar under scaling about its apex), so these figures rely on the final refinement on
// the wider level-0 window (AlignmentOptions::scale_window_stride); every miss is printed.
void ExpectAccurate(const WarpErrors& errors) {
  int position_within = 0;
  for (double e : errors.centre_position) position_within += e < 0.1;
  std::printf("  centre corners tracked %d / %d; within 0.1 px: %d; within 0.1 px and 1 %% scale: %d\n",
              errors.centre_tracked, errors.centre_cases, position_within, errors.centre_within);
  EXPECT_GE(errors.centre_tracked, 0.9 * errors.centre_cases);
  EXPECT_EQ(errors.centre_within, errors.centre_tracked);
  EXPECT_LT(Percentile(errors.centre_position, 1.0), 0.1);
  EXPECT_LT(Percentile(errors.centre_scale, 1.0), 0.01);
  EXPECT_GE(errors.position.size(), 300u);
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
  ExpectAccurate(errors);
}

TEST(FeatureTracker, RecoversSyntheticWarpsOfKittiFrame) {
  const cv::Mat kitti = LoadKittiFrameOrEmpty();
  if (kitti.empty()) GTEST_SKIP() << "kitti07 not found; skipping";
  const WarpRenderer render = [&](const ImageWarp& warp) { return WarpImage(kitti, warp); };
  const WarpErrors errors = RunSyntheticWarps(render, 60, 11);
  ExpectAccurate(errors);
}

SyntheticTexture SmallTexture(uint64_t seed) {
  SyntheticTextureOptions options;
  options.width = 320;
  options.height = 240;
  options.num_shapes = 250;
  options.seed = seed;
  return SyntheticTexture(options);
}

// Two surfaces lit differently by another sun: vertical bands 20 px wide, every other one at gain 0.45 and bias +60.
bool InLitBand(double x) { return static_cast<int>(std::floor(x / 20.0)) % 2 == 1; }

// `texture` moved by `shift`, with the columns x whose x - `bands_origin_x` is in a lit band (InLitBand) relit.
cv::Mat RenderLitInBands(const SyntheticTexture& texture, const Vector2d& shift, double bands_origin_x) {
  cv::Mat image = Quantise(texture.Render(320, 240, 1.0, shift));
  for (int r = 0; r < image.rows; ++r) {
    for (int c = 0; c < image.cols; ++c) {
      if (InLitBand(c - bands_origin_x)) {
        image.at<uint8_t>(r, c) = cv::saturate_cast<uint8_t>(0.45 * image.at<uint8_t>(r, c) + 60.0);
      }
    }
  }
  return image;
}

// Features tracked over a translating view while an occluder (a patch of another texture) slides over part of
// the image: a feature may be lost, but a feature reported as tracked is never off its true position.
TEST(FeatureTracker, OccluderMakesTracksFailInsteadOfDrifting) {
  const SyntheticTexture texture = SmallTexture(3);
  const cv::Mat occluder_texture = Quantise(SmallTexture(99).Render(320, 240));
  const Vector2d velocity(1.5, 0.7);
  // Occluder: a 40x40 square entering from the left at 6 px per frame from frame 3, at rows 90..130.
  auto occluder_rect = [](int frame) { return cv::Rect(-40 + 6 * std::max(0, frame - 3) * 4, 90, 40, 40); };
  auto render = [&](int frame) {
    cv::Mat image = Quantise(texture.Render(320, 240, 1.0, frame * velocity));
    const cv::Rect r = occluder_rect(frame) & cv::Rect(0, 0, 320, 240);
    if (r.area() > 0) occluder_texture(r).copyTo(image(r));
    return image;
  };
  ImagePyramid pyramid(render(0));
  CornerDetectorOptions detector;
  detector.max_corners = 150;
  FeatureTracker tracker;
  std::vector<Vector2d> positions;
  for (const Corner& c : DetectCorners(pyramid, detector)) positions.push_back(c.position);
  tracker.AddFeatures(pyramid, positions);
  std::map<feature_t, Vector2d> start;
  for (const TrackedFeature& f : tracker.Features()) start[f.id] = f.warp.position;
  ASSERT_GE(tracker.NumFeatures(), 80);
  int occluded_and_rejected = 0, partially_covered_tracked = 0;
  double max_error_free = 0.0, max_error_partial = 0.0;
  for (int frame = 1; frame <= 20; ++frame) {
    pyramid.Build(render(frame));
    const cv::Rect occ = occluder_rect(frame);
    for (const TrackedFeature& f : tracker.Track(pyramid)) {
      const Vector2d truth = start[f.id] + frame * velocity;
      // Fraction of the 15x15 window under the occluder.
      const cv::Rect window(static_cast<int>(std::lround(truth.x())) - 7,
                            static_cast<int>(std::lround(truth.y())) - 7, 15, 15);
      const double covered = static_cast<double>((window & occ).area()) / window.area();
      if (f.status == TrackStatus::kTracked) {
        const double error = (f.warp.position - truth).norm();
        if (covered == 0.0) {
          max_error_free = std::max(max_error_free, error);
          EXPECT_LT(error, 0.2) << "feature " << f.id << " frame " << frame;
        } else {
          max_error_partial = std::max(max_error_partial, error);
          ++partially_covered_tracked;
        }
        EXPECT_LT(covered, 0.5) << "feature " << f.id << " frame " << frame
                                << " tracked under the occluder, error " << error << " residual "
                                << f.residual;
      } else if (covered > 0.0) {
        ++occluded_and_rejected;
      }
    }
  }
  std::printf(
      "  occluded features rejected: %d; max error of tracked features: %.3f px when free, %.3f px when "
      "partly (< 50%%) covered (%d cases); survivors %d\n",
      occluded_and_rejected, max_error_free, max_error_partial, partially_covered_tracked,
      tracker.NumFeatures());
  EXPECT_GE(occluded_and_rejected, 3);
  EXPECT_GE(tracker.NumFeatures(), 40);
}

// A single feature under a pasted occluder: the alignment fails with a residual above R (or does not
// converge), it does not report the feature as tracked.
TEST(FeatureTracker, OccludedFeatureIsRejected) {
  const SyntheticTexture texture = SmallTexture(5);
  const cv::Mat image0 = Quantise(texture.Render(320, 240));
  const ImagePyramid pyramid0(image0);
  CornerDetectorOptions detector;
  detector.max_corners = 20;
  detector.border = 40;
  const std::vector<Corner> corners = DetectCorners(pyramid0, detector);
  ASSERT_GE(corners.size(), 10u);
  const cv::Mat other = Quantise(SmallTexture(77).Render(320, 240));
  int rejected = 0;
  for (const Corner& c : corners) {
    ReferencePatch reference;
    ASSERT_TRUE(reference.Create(pyramid0, c.position));
    cv::Mat image1 = Quantise(texture.Render(320, 240, 1.0, Vector2d(2.0, 1.0)));
    const cv::Rect r(static_cast<int>(c.position.x()) - 10, static_cast<int>(c.position.y()) - 10, 24, 24);
    other(r).copyTo(image1(r));
    WarpState initial;
    initial.position = c.position;
    const AlignmentResult result =
        AlignToReference(ImagePyramid(image1), reference, initial, AlignmentOptions());
    EXPECT_FALSE(result.ok()) << "corner at " << c.position.transpose() << " residual " << result.residual;
    if (result.converged) {
      EXPECT_GT(result.residual, AlignmentOptions().max_residual);
    }
    rejected += !result.ok();
  }
  EXPECT_EQ(rejected, static_cast<int>(corners.size()));
}

// RefinePrediction: a prediction 1.8 px off with a roughly right scale is accepted and refined; a prediction
// far from the feature, and a prediction onto an occluded feature, are rejected.
TEST(FeatureTracker, RefinePredictionAcceptsOnlyNearThePrediction) {
  const SyntheticTexture texture = SmallTexture(8);
  const ImagePyramid pyramid0(Quantise(texture.Render(320, 240)));
  CornerDetectorOptions detector;
  detector.max_corners = 30;
  detector.border = 50;
  const std::vector<Corner> corners = DetectCorners(pyramid0, detector);
  ASSERT_GE(corners.size(), 10u);
  const double true_scale = 1.15;
  const Vector2d centre(160.0, 120.0), shift(20.0, -12.0);
  // Large motion (as after a gap): texture point X appears at centre + s (X - centre) + shift.
  const cv::Mat image1 =
      Quantise(texture.Render(320, 240, true_scale, centre * (1.0 - true_scale) + shift, 0.8, 12.0));
  const ImagePyramid pyramid1(image1);
  RefinePredictionOptions options;
  int accepted = 0, far_rejected = 0;
  std::vector<double> errors;
  for (const Corner& c : corners) {
    ReferencePatch reference;
    ASSERT_TRUE(reference.Create(pyramid0, c.position));
    const Vector2d truth = centre + true_scale * (c.position - centre) + shift;
    if (truth.x() < 20 || truth.y() < 20 || truth.x() > 300 || truth.y() > 220) continue;
    const AlignmentResult near =
        RefinePrediction(pyramid1, reference, truth + Vector2d(1.5, -1.0), 1.1, options);
    if (near.ok()) {
      ++accepted;
      errors.push_back((near.warp.position - truth).norm());
      EXPECT_LT(errors.back(), 0.15);
      EXPECT_NEAR(near.warp.scale, true_scale, 0.05);
    }
    // 12 px away: either rejected, or (never) accepted somewhere else.
    const AlignmentResult far =
        RefinePrediction(pyramid1, reference, truth + Vector2d(12.0, 0.0), 1.1, options);
    EXPECT_FALSE(far.ok()) << "accepted at " << far.warp.position.transpose() << ", truth "
                           << truth.transpose();
    far_rejected += !far.ok();
  }
  std::printf("  predictions accepted %d, median error %.4f px; far predictions rejected %d\n", accepted,
              Percentile(errors, 0.5), far_rejected);
  EXPECT_GE(accepted, static_cast<int>(0.8 * far_rejected));
  EXPECT_GE(accepted, 8);
}

// The image mapped by x_new = centre + A (x - centre) + shift (cubic, edges reflected): a facade seen from elsewhere.
cv::Mat WarpAboutCentre(const cv::Mat& source, const Eigen::Matrix2d& a, const Vector2d& centre,
                        const Vector2d& shift) {
  cv::Mat forward(2, 3, CV_64F);
  for (int r = 0; r < 2; ++r) {
    for (int c = 0; c < 2; ++c) forward.at<double>(r, c) = a(r, c);
    forward.at<double>(r, 2) = (centre - a * centre + shift)(r);
  }
  cv::Mat warped;
  cv::warpAffine(source, warped, forward, source.size(), cv::INTER_CUBIC, cv::BORDER_REFLECT);
  return warped;
}

// Up to 40 corners of `pyramid` at least 50 px from its border (the affine tests' features).
std::vector<Corner> AffineTestCorners(const ImagePyramid& pyramid) {
  CornerDetectorOptions detector;
  detector.max_corners = 40;
  detector.border = 50;
  return DetectCorners(pyramid, detector);
}

// A facade seen from beside the path it was taught on: the image is compressed horizontally (0.7) and sheared
// vertically (0.25) about its centre, beyond the paper's translation + isotropic scale. With the paper's warp alone
// most predicted features are rejected for their residual; the affine fallback accepts most of them, at the right
// position (those whose residual under the paper's warp is within 1.5 R). (The few that the paper's warp accepts within
// R are off by 0.2-0.8 px: a window sheared this much still matches an isotropic warp at a shifted centre. The fallback
// does not touch those.)
TEST(FeatureTracker, AffineFallbackAlignsShearedAppearance) {
  const SyntheticTexture texture = SmallTexture(8);
  const cv::Mat source = texture.Render(320, 240);
  const ImagePyramid pyramid0(Quantise(source));
  const std::vector<Corner> corners = AffineTestCorners(pyramid0);
  ASSERT_GE(corners.size(), 20u);
  Eigen::Matrix2d a;
  a << 0.7, 0.0, 0.25, 1.0;
  const Vector2d centre(160.0, 120.0), shift(3.0, -2.0);
  const ImagePyramid pyramid1(Quantise(WarpAboutCentre(source, a, centre, shift)));
  RefinePredictionOptions paper, fallback;
  fallback.alignment.affine_fallback = true;
  int tried = 0, accepted_paper = 0, adopted_affine = 0;
  std::vector<double> paper_errors, affine_errors;
  for (const Corner& c : corners) {
    ReferencePatch reference;
    ASSERT_TRUE(reference.Create(pyramid0, c.position));
    const Vector2d truth = centre + a * (c.position - centre) + shift;
    if (truth.x() < 30 || truth.y() < 30 || truth.x() > 290 || truth.y() > 210) continue;
    ++tried;
    const Vector2d predicted = truth + Vector2d(1.0, 0.5);
    const AlignmentResult plain = RefinePrediction(pyramid1, reference, predicted, 0.85, paper);
    EXPECT_FALSE(plain.affine_used);
    if (plain.ok()) {
      ++accepted_paper;
      paper_errors.push_back((plain.warp.position - truth).norm());
    }
    const AlignmentResult result = RefinePrediction(pyramid1, reference, predicted, 0.85, fallback);
    if (!result.ok() || !result.affine_used) continue;
    EXPECT_FALSE(plain.ok());  // the fallback only follows a rejection
    ++adopted_affine;
    affine_errors.push_back((result.warp.position - truth).norm());
    EXPECT_LT(affine_errors.back(), 0.25) << "corner at " << c.position.transpose();
    EXPECT_NEAR(result.warp.scale, std::sqrt(a.determinant()), 0.08);  // sqrt(det A)
  }
  std::printf(
      "  sheared: %d predictions; the paper's warp accepts %d (median error %.3f px), the affine fallback "
      "%d more (median error %.3f px)\n",
      tried, accepted_paper, Percentile(paper_errors, 0.5), adopted_affine, Percentile(affine_errors, 0.5));
  ASSERT_GE(tried, 30);
  EXPECT_LT(accepted_paper, tried / 2);
  EXPECT_GE(adopted_affine, tried / 4);
  EXPECT_GE(accepted_paper + adopted_affine, (3 * tried) / 5);
  EXPECT_LT(Percentile(affine_errors, 0.5), 0.12);
}

// A view whose windows are sheared a little (as a facade seen from beside the taught path): the paper's warp accepts
// them within R at a shifted centre, the affine refinement moves them back. And in an undistorted view it does not
// move them (it only has more parameters to fit the same window).
TEST(FeatureTracker, AffineRefinementRemovesTheShearBias) {
  const SyntheticTexture texture = SmallTexture(8);
  const cv::Mat source = texture.Render(320, 240);
  const ImagePyramid pyramid0(Quantise(source));
  const std::vector<Corner> corners = AffineTestCorners(pyramid0);
  ASSERT_GE(corners.size(), 20u);
  const Vector2d centre(160.0, 120.0), shift(2.0, -1.5);
  const auto errors = [&](const Eigen::Matrix2d& a, bool refine, int* accepted, int* refined) {
    const ImagePyramid pyramid1(Quantise(WarpAboutCentre(source, a, centre, shift)));
    RefinePredictionOptions options;
    options.alignment.affine_refinement = refine;
    std::vector<double> found;
    *accepted = *refined = 0;
    for (const Corner& c : corners) {
      ReferencePatch reference;
      EXPECT_TRUE(reference.Create(pyramid0, c.position));
      const Vector2d truth = centre + a * (c.position - centre) + shift;
      if (truth.x() < 30 || truth.y() < 30 || truth.x() > 290 || truth.y() > 210) continue;
      const AlignmentResult result =
          RefinePrediction(pyramid1, reference, truth + Vector2d(0.8, -0.6), std::sqrt(a.determinant()), options);
      if (!result.ok()) continue;
      ++*accepted;
      *refined += result.affine_used;
      found.push_back((result.warp.position - truth).norm());
    }
    return found;
  };
  Eigen::Matrix2d sheared;
  sheared << 0.9, 0.0, 0.12, 1.0;
  int paper_accepted = 0, refined_accepted = 0, none = 0, refined = 0;
  const std::vector<double> paper = errors(sheared, false, &paper_accepted, &none);
  const std::vector<double> affine = errors(sheared, true, &refined_accepted, &refined);
  std::printf(
      "  sheared 0.12, compressed 0.9: the paper's warp accepts %d (median error %.3f px, 90th pct %.3f); "
      "refined %d of %d accepted (median error %.3f px, 90th pct %.3f)\n",
      paper_accepted, Percentile(paper, 0.5), Percentile(paper, 0.9), refined, refined_accepted,
      Percentile(affine, 0.5), Percentile(affine, 0.9));
  EXPECT_EQ(none, 0);  // without the option nothing is refined
  ASSERT_GE(paper_accepted, 20);
  // The refinement only moves accepted windows (one the paper's warp left too far from the prediction may come back).
  EXPECT_GE(refined_accepted, paper_accepted);
  EXPECT_GE(refined, (3 * refined_accepted) / 4);
  EXPECT_LT(Percentile(affine, 0.5), 0.5 * Percentile(paper, 0.5));
  EXPECT_LT(Percentile(affine, 0.5), 0.05);

  int plain_accepted = 0, plain_refined_accepted = 0;
  const std::vector<double> plain = errors(Eigen::Matrix2d::Identity(), false, &plain_accepted, &none);
  const std::vector<double> plain_refined =
      errors(Eigen::Matrix2d::Identity(), true, &plain_refined_accepted, &refined);
  std::printf("  undistorted: median error %.3f px with the paper's warp, %.3f px refined\n", Percentile(plain, 0.5),
              Percentile(plain_refined, 0.5));
  EXPECT_EQ(plain_refined_accepted, plain_accepted);
  EXPECT_LT(Percentile(plain_refined, 0.5), 0.05);
  EXPECT_LT(Percentile(plain_refined, 0.9), 0.1);
}

// Under another sun a window may straddle two surfaces whose brightness changed differently (a facade and the sky, a
// wall and its windows): here vertical bands 20 px wide alternate between the texture as it was and the texture at
// gain 0.45 and bias +60, moved by (2, -1) px, and windows are predicted 1.1 px off. Of the windows crossing a band's
// edge with 5-25 % of their pixels on its other side, the paper's warp accepts some (off by 0.16 px at the median, up
// to 0.6: the edge pulls them) and rejects the others; the robust fallback adopts most of those it rejects, at the
// true position but for at most one (a band's edge along an edge of the texture, taken for it: 1.4 px off). It adopts
// no prediction 12 px off, and fewer than half of the windows a second texture covers 40 % of — but some, off by a few
// tenths of a pixel (which is why a relocalization does not take a place on them, LocalizerOptions::
// relocalization_robust_alignment). When written: 28 by the paper's warp, 8 more by the fallback at 0.06 px median
// error; 7 of 20 covered windows, 0.14-0.77 px off.
TEST(FeatureTracker, RobustFallbackAlignsAWindowLitTwoWays) {
  const SyntheticTexture texture = SmallTexture(8);
  const ImagePyramid pyramid0(Quantise(texture.Render(320, 240)));
  CornerDetectorOptions detector;
  detector.max_corners = 400;
  detector.border = 30;
  const std::vector<Corner> corners = DetectCorners(pyramid0, detector);
  const Vector2d shift(2.0, -1.0);
  const cv::Mat image1 = RenderLitInBands(texture, shift, 0.0);  // the bands fixed in the image
  const ImagePyramid pyramid1(image1);
  const cv::Mat other = Quantise(SmallTexture(77).Render(320, 240));
  RefinePredictionOptions paper, robust;
  robust.alignment.robust_fallback = true;
  int straddling = 0, accepted_paper = 0, adopted_robust = 0, far_accepted = 0, covered_tried = 0, covered_adopted = 0;
  std::vector<double> paper_errors, robust_errors;
  for (const Corner& c : corners) {
    const Vector2d truth = c.position + shift;
    const int left = static_cast<int>(std::lround(truth.x())) - 7;
    int other_side = 0;
    for (int k = 0; k < 15; ++k) other_side += InLitBand(left + k) != InLitBand(truth.x());
    const double share = other_side / 15.0;
    if (share < 0.05 || share > 0.25) continue;
    ReferencePatch reference;
    if (!reference.Create(pyramid0, c.position)) continue;
    ++straddling;
    const Vector2d predicted = truth + Vector2d(1.0, 0.5);
    const AlignmentResult plain = RefinePrediction(pyramid1, reference, predicted, 1.0, paper);
    EXPECT_FALSE(plain.robust_used);
    if (plain.ok()) {
      ++accepted_paper;
      paper_errors.push_back((plain.warp.position - truth).norm());
    }
    const AlignmentResult result = RefinePrediction(pyramid1, reference, predicted, 1.0, robust);
    if (plain.ok()) {
      EXPECT_TRUE(result.ok() && !result.robust_used);  // the fallback only follows a rejection
    }
    if (result.ok() && result.robust_used) {
      ASSERT_FALSE(plain.ok());
      ++adopted_robust;
      robust_errors.push_back((result.warp.position - truth).norm());
      EXPECT_LE(result.residual, robust.alignment.max_residual);
    }
    const AlignmentResult far = RefinePrediction(pyramid1, reference, truth + Vector2d(12.0, 0.0), 1.0, robust);
    far_accepted += far.ok();
    // The same window with a second texture over its left 6 of 15 columns.
    if (covered_tried < 20) {
      cv::Mat image = image1.clone();
      const cv::Rect covered(left, static_cast<int>(std::lround(truth.y())) - 7, 6, 15);
      other(covered).copyTo(image(covered));
      ++covered_tried;
      const AlignmentResult covered_result = RefinePrediction(ImagePyramid(image), reference, predicted, 1.0, robust);
      covered_adopted += covered_result.ok() && covered_result.robust_used;
    }
  }
  std::printf(
      "  %d windows straddle two lightings: the paper's warp accepts %d (median error %.3f px, max %.3f), the robust "
      "fallback %d more (median error %.3f px, max %.3f); 12 px off accepted %d; 40 %% covered adopted %d of %d\n",
      straddling, accepted_paper, Percentile(paper_errors, 0.5),
      paper_errors.empty() ? 0.0 : *std::max_element(paper_errors.begin(), paper_errors.end()), adopted_robust,
      Percentile(robust_errors, 0.5),
      robust_errors.empty() ? 0.0 : *std::max_element(robust_errors.begin(), robust_errors.end()), far_accepted,
      covered_adopted, covered_tried);
  ASSERT_GE(straddling, 30);
  const int rejected = straddling - accepted_paper;
  ASSERT_GE(rejected, 10);
  EXPECT_GE(adopted_robust, rejected / 2);
  EXPECT_LT(Percentile(robust_errors, 0.5), 0.1);
  EXPECT_LT(Percentile(robust_errors, 0.5), Percentile(paper_errors, 0.5));
  EXPECT_LE(std::count_if(robust_errors.begin(), robust_errors.end(), [](double e) { return e > 0.3; }), 1);
  EXPECT_EQ(far_accepted, 0);
  EXPECT_LT(covered_adopted, covered_tried / 2);
}

// A feature the robust fallback located keeps straddling its two surfaces in the next frames: with
// FeatureTrackerOptions::robust_acquired_tracking it is tracked with the fallback (and stays at the truth), without it
// the paper's warp loses most such features at the next frame. Bands lit at gain 0.45 and bias +60 move with the
// texture here (the surfaces move with the scene). When written: 17 features adopted robustly, 17 kept with the option
// at 0.066 px median error, 3 without it.
TEST(FeatureTracker, RobustlyAcquiredFeaturesAreTrackedRobustly) {
  const SyntheticTexture texture = SmallTexture(8);
  const ImagePyramid pyramid0(Quantise(texture.Render(320, 240)));
  CornerDetectorOptions detector;
  detector.max_corners = 400;
  detector.border = 30;
  const std::vector<Corner> corners = DetectCorners(pyramid0, detector);
  const Vector2d shift1(2.0, -1.0), shift2(3.5, -0.5);
  const ImagePyramid pyramid1(RenderLitInBands(texture, shift1, shift1.x()));  // the bands move with the texture
  const ImagePyramid pyramid2(RenderLitInBands(texture, shift2, shift2.x()));
  RefinePredictionOptions paper, robust;
  robust.alignment.robust_fallback = true;
  FeatureTrackerOptions with_option, without_option;
  with_option.robust_acquired_tracking = true;
  FeatureTracker tracker_with(with_option), tracker_without(without_option);
  std::vector<Vector2d> positions;  // in frame 0, by feature id
  for (const Corner& c : corners) {
    auto reference = std::make_shared<ReferencePatch>();
    if (!reference->Create(pyramid0, c.position)) continue;
    const Vector2d predicted = c.position + shift1 + Vector2d(1.0, 0.5);
    if (RefinePrediction(pyramid1, *reference, predicted, 1.0, paper).ok()) continue;
    const AlignmentResult result = RefinePrediction(pyramid1, *reference, predicted, 1.0, robust);
    if (!result.ok() || !result.robust_used) continue;
    if ((result.warp.position - (c.position + shift1)).norm() > 0.3) continue;  // the one taken for an edge
    const feature_t id = static_cast<feature_t>(positions.size());
    positions.push_back(c.position);
    ASSERT_EQ(tracker_with.AddFeature(reference, result, id), id);
    ASSERT_EQ(tracker_without.AddFeature(reference, result, id), id);
  }
  ASSERT_GE(tracker_with.NumRobustFeatures(), 5);
  EXPECT_EQ(tracker_with.NumRobustFeatures(), tracker_with.NumFeatures());
  tracker_with.Track(pyramid2);
  tracker_without.Track(pyramid2);
  std::vector<double> errors;
  for (const TrackedFeature& f : tracker_with.Features()) {
    EXPECT_TRUE(f.robust_acquired);
    errors.push_back((f.warp.position - (positions[f.id] + shift2)).norm());
  }
  std::printf("  %zu features adopted robustly; kept with robust tracking %d (median error %.3f px), without %d\n",
              positions.size(), tracker_with.NumFeatures(), Percentile(errors, 0.5), tracker_without.NumFeatures());
  EXPECT_GE(tracker_with.NumFeatures(), static_cast<int>(positions.size()) * 3 / 4);
  EXPECT_LT(Percentile(errors, 0.5), 0.1);
  EXPECT_LT(*std::max_element(errors.begin(), errors.end()), 0.5);
  EXPECT_LT(tracker_without.NumFeatures(), tracker_with.NumFeatures() / 2);
}

TEST(FeatureTracker, AddRemoveSetReference) {
  const SyntheticTexture texture = SmallTexture(4);
  const ImagePyramid pyramid0(Quantise(texture.Render(320, 240)));
  FeatureTracker tracker;
  const feature_t a = tracker.AddFeature(pyramid0, Vector2d(100.0, 100.0));
  const feature_t b = tracker.AddFeature(pyramid0, Vector2d(200.0, 150.0), 42);
  EXPECT_EQ(a, 0);
  EXPECT_EQ(b, 42);
  EXPECT_EQ(tracker.AddFeature(pyramid0, Vector2d(2.0, 2.0)), kInvalidFeatureId);  // no window at the border
  EXPECT_EQ(tracker.AddFeature(pyramid0, Vector2d(150.0, 150.0), 42), kInvalidFeatureId);  // duplicate id
  EXPECT_EQ(tracker.NumFeatures(), 2);
  const ImagePyramid pyramid1(Quantise(texture.Render(320, 240, 1.0, Vector2d(3.0, -2.0))));
  tracker.Track(pyramid1);
  ASSERT_NE(tracker.Find(b), nullptr);
  EXPECT_NEAR(tracker.Find(b)->warp.position.x(), 203.0, 0.1);
  EXPECT_NEAR(tracker.Find(b)->warp.position.y(), 148.0, 0.1);
  EXPECT_TRUE(tracker.SetReference(b, pyramid1, Vector2d(203.0, 148.0)));
  EXPECT_NEAR(tracker.Reference(b)->Position().x(), 203.0, 1e-12);
  EXPECT_TRUE(tracker.Remove(a));
  EXPECT_FALSE(tracker.Remove(a));
  EXPECT_EQ(tracker.NumFeatures(), 1);
}

// A reference given as a shared patch is tracked against that very patch (the localizer cuts each key-image's
// reference once and every track of the feature shares it), stays valid when the caller drops its handle, and
// removing other features does not disturb it. Both forms of AddFeature track alike.
TEST(FeatureTracker, SharedReferenceIsTrackedWithoutACopy) {
  const SyntheticTexture texture = SmallTexture(4);
  const ImagePyramid pyramid0(Quantise(texture.Render(320, 240)));
  const ImagePyramid pyramid1(Quantise(texture.Render(320, 240, 1.0, Vector2d(3.0, -2.0))));
  FeatureTracker tracker;
  AlignmentResult at_reference;
  at_reference.warp.position = Vector2d(200.0, 150.0);
  at_reference.residual = 0.0;
  at_reference.converged = true;
  at_reference.status = TrackStatus::kTracked;
  auto patch = std::make_shared<ReferencePatch>();
  ASSERT_TRUE(patch->Create(pyramid0, at_reference.warp.position));
  const ReferencePatch* const shared = patch.get();
  EXPECT_EQ(tracker.AddFeature(std::shared_ptr<const ReferencePatch>(), at_reference), kInvalidFeatureId);
  const feature_t copied = tracker.AddFeature(*patch, at_reference, 1);
  const feature_t other = tracker.AddFeature(pyramid0, Vector2d(100.0, 100.0), 2);
  const feature_t id = tracker.AddFeature(std::shared_ptr<const ReferencePatch>(std::move(patch)), at_reference, 3);
  ASSERT_EQ(id, 3);
  ASSERT_EQ(copied, 1);
  EXPECT_EQ(tracker.Reference(id), shared);
  EXPECT_NE(tracker.Reference(copied), shared);
  EXPECT_TRUE(tracker.Remove(other));
  tracker.Track(pyramid1);
  ASSERT_NE(tracker.Find(id), nullptr);
  ASSERT_NE(tracker.Find(copied), nullptr);
  EXPECT_EQ(tracker.Reference(id), shared);
  EXPECT_NEAR(tracker.Find(id)->warp.position.x(), 203.0, 0.1);
  EXPECT_NEAR(tracker.Find(id)->warp.position.y(), 148.0, 0.1);
  EXPECT_EQ(tracker.Find(id)->warp.position, tracker.Find(copied)->warp.position);
}
// The wide level-0 window of the final refinement is cut at its first use, from the part of the image the patch
// copied when it was created: the values are the image's cubic samples at stride 3 around the position (Keys
// kernel in double here), also where the window reaches the image's border, whatever becomes of the pyramid
// after Create (a copied part, or a handle to a key-image's level 0); a window that does not fit is none, the patch
// still valid.
TEST(FeatureTracker, ScaleWindowIsCutLaterFromTheImageAsCreated) {
  const SyntheticTexture texture = SmallTexture(4);
  const cv::Mat image0 = Quantise(texture.Render(320, 240));
  ImagePyramid pyramid(image0);
  const cv::Mat level0 = pyramid.Level(0).clone();
  const int w = 15, stride = 3, half = w / 2, n = w * w;
  // The wide window with its gradient border reaches (w - 1) * stride / 2 + 2 = 23 px and its cubic taps 2 more.
  const std::vector<Vector2d> positions = {{160.3, 120.7}, {24.5, 30.2}, {295.2, 215.9}, {200.0, 150.0}};
  std::vector<ReferencePatch> patches(positions.size());
  for (size_t i = 0; i < positions.size(); ++i) ASSERT_TRUE(patches[i].Create(pyramid, positions[i], w, 3, stride));
  ReferencePatch kept;  // keeps a handle to level 0 of a key-image's pyramid, which is gone before the cut
  {
    const ImagePyramid key_image_pyramid(image0);
    ASSERT_TRUE(kept.Create(key_image_pyramid, positions[0], w, 3, stride, ReferencePatch::PatchImage::kKept));
  }
  const ReferencePatch copy = patches[0];  // copied before its window is cut
  ReferencePatch beyond;                   // its wide window leaves the image by half a pixel
  ASSERT_TRUE(beyond.Create(pyramid, Vector2d(22.5, 120.0), w, 3, stride));
  const int first_cut_early = patches[3].ScaleWindowStride();
  // The pyramid object now holds another image (its buffers reused or not).
  pyramid.Build(Quantise(texture.Render(320, 240, 1.1, Vector2d(-7.0, 4.0))));
  EXPECT_EQ(first_cut_early, stride);
  EXPECT_EQ(beyond.ScaleWindowStride(), 0);
  EXPECT_TRUE(beyond.Valid());
  const auto sample = [&](double x, double y) {
    const int fx = static_cast<int>(std::floor(x)), fy = static_cast<int>(std::floor(y));
    double value = 0.0;
    for (int j = -1; j <= 2; ++j) {
      for (int i = -1; i <= 2; ++i)
        value += Cubic(x - (fx + i)) * Cubic(y - (fy + j)) * level0.at<float>(fy + j, fx + i);
    }
    return value;
  };
  for (size_t i = 0; i < positions.size(); ++i) {
    const ReferencePatch& patch = patches[i];
    ASSERT_EQ(patch.ScaleWindowStride(), stride) << "position " << i;
    double worst = 0.0;
    for (int r = 0; r < w; ++r) {
      for (int c = 0; c < w; ++c) {
        const double expected = sample(positions[i].x() + (c - half) * stride, positions[i].y() + (r - half) * stride);
        worst = std::max(worst, std::abs(patch.ScaleWindow()[r * w + c] + patch.ScaleWindowMean() - expected));
      }
    }
    EXPECT_LT(worst, 1e-3) << "position " << i;
  }
  // The copy cuts the same window, to the bit.
  ASSERT_EQ(copy.ScaleWindowStride(), stride);
  EXPECT_EQ(std::vector<float>(copy.ScaleWindow(), copy.ScaleWindow() + 4 * n),
            std::vector<float>(patches[0].ScaleWindow(), patches[0].ScaleWindow() + 4 * n));
  EXPECT_EQ(copy.ScaleWindowMean(), patches[0].ScaleWindowMean());
  ASSERT_EQ(kept.ScaleWindowStride(), stride);
  EXPECT_EQ(std::vector<float>(kept.ScaleWindow(), kept.ScaleWindow() + 4 * n),
            std::vector<float>(patches[0].ScaleWindow(), patches[0].ScaleWindow() + 4 * n));
}

// Features tracked in the previous frame start the alignment at a finer level from their constant-velocity guess
// (FeatureTrackerOptions::predicted_start_level); when the motion reverses abruptly, the guess is 15 px off,
// outside the basin of the start level, and the fallback to the full coarse-to-fine alignment must keep the tracks.
TEST(FeatureTracker, AbruptMotionChangeFallsBackToCoarseToFine) {
  const SyntheticTexture texture = SmallTexture(4);
  const std::vector<double> shifts = {0.0, 2.7, 5.4, 8.1, -4.3};  // x translation of each frame
  CornerDetectorOptions detector;
  detector.max_corners = 60;
  detector.min_distance = 10.0;
  for (const int start_level : {0, 1, -1}) {
    FeatureTrackerOptions options;
    options.predicted_start_level = start_level;
    FeatureTracker tracker(options);
    std::map<feature_t, Vector2d> initial;
    for (size_t f = 0; f < shifts.size(); ++f) {
      const ImagePyramid pyramid(Quantise(texture.Render(320, 240, 1.0, Vector2d(shifts[f], 0.0))));
      if (f == 0) {
        std::vector<Vector2d> positions;
        for (const Corner& c : DetectCorners(pyramid, detector)) {
          // Away from the border, so that no window leaves the image during the motion.
          if (c.position.x() > 40.0 && c.position.x() < 280.0 && c.position.y() > 30.0 && c.position.y() < 210.0)
            positions.push_back(c.position);
        }
        const std::vector<feature_t> ids = tracker.AddFeatures(pyramid, positions);
        for (size_t i = 0; i < ids.size(); ++i) {
          if (ids[i] != kInvalidFeatureId) initial[ids[i]] = positions[i];
        }
        ASSERT_GE(initial.size(), 20u);
        continue;
      }
      tracker.Track(pyramid);
    }
    double max_error = 0.0;
    for (const TrackedFeature& feature : tracker.Features()) {
      max_error = std::max(max_error, (feature.warp.position - initial[feature.id] - Vector2d(shifts.back(), 0.0)).norm());
    }
    std::printf("  start level %d: %d of %zu features tracked through the reversal, max error %.4f px\n",
                start_level, tracker.NumFeatures(), initial.size(), max_error);
    EXPECT_GE(tracker.NumFeatures(), static_cast<int>(0.9 * initial.size()));
    EXPECT_LT(max_error, 0.1);
  }
}

// A feature placed by RefinePrediction has a reference cut from another view (a key-image): only its finest windows
// were checked against this image, and its coarsest ones (60 px wide) may see surroundings that moved otherwise (other
// depths: parallax), onto which they slide. Here each feature's neighbourhood (±16 px) stays where the reference image
// has it and everything else is shifted by 16 px (a background seen from beside the taught path), and the camera
// stands still for three frames: with FeatureTrackerOptions::placed_features_start_fine they start at
// predicted_start_level and stay where they were placed; without, having no velocity of their own, they start at the
// coarsest level and a quarter or more are lost (7 of 17 here; in the simulated town, standing still after a
// relocalization: 16 of 19).
TEST(FeatureTracker, FeaturePlacedFromAnotherViewKeepsItsFineAlignment) {
  const cv::Mat reference_image = SmallTexture(8).Render(320, 240);
  const ImagePyramid reference_pyramid(Quantise(reference_image));
  CornerDetectorOptions detector;
  detector.max_corners = 40;
  detector.border = 40;
  detector.min_distance = 45.0;
  const std::vector<Corner> corners = DetectCorners(reference_pyramid, detector);
  ASSERT_GE(corners.size(), 12u);
  // The current image: the reference image shifted by (16, 4) px, but for the neighbourhood of each corner.
  cv::Mat current;
  const cv::Mat shift = (cv::Mat_<double>(2, 3) << 1.0, 0.0, 16.0, 0.0, 1.0, 4.0);
  cv::warpAffine(reference_image, current, shift, reference_image.size(), cv::INTER_CUBIC, cv::BORDER_REFLECT);
  constexpr int kKept = 16;
  for (const Corner& c : corners) {
    const cv::Rect around(static_cast<int>(std::lround(c.position.x())) - kKept,
                          static_cast<int>(std::lround(c.position.y())) - kKept, 2 * kKept + 1, 2 * kKept + 1);
    reference_image(around & cv::Rect(0, 0, 320, 240)).copyTo(current(around & cv::Rect(0, 0, 320, 240)));
  }
  const ImagePyramid pyramid(Quantise(current));
  const ImagePyramid fine_levels = pyramid.FinestLevels(pyramid.NumLevels() - 1);
  for (const bool start_fine : {true, false}) {
    FeatureTrackerOptions options;
    options.placed_features_start_fine = start_fine;
    FeatureTracker tracker(options);
    std::map<feature_t, Vector2d> placed;
    for (const Corner& c : corners) {
      ReferencePatch reference;
      ASSERT_TRUE(reference.Create(reference_pyramid, c.position));
      // Placed as the localizer places a mapped feature: a prediction refined on the finest levels.
      const AlignmentResult refined =
          RefinePrediction(fine_levels, reference, c.position + Vector2d(0.8, -0.6), 1.0, RefinePredictionOptions());
      if (!refined.ok()) continue;
      const feature_t id = tracker.AddFeature(reference, refined);
      ASSERT_NE(id, kInvalidFeatureId);
      placed[id] = c.position;
    }
    ASSERT_GE(placed.size(), 10u);
    for (int frame = 0; frame < 3; ++frame) tracker.Track(pyramid);
    double max_error = 0.0;
    for (const TrackedFeature& feature : tracker.Features()) {
      max_error = std::max(max_error, (feature.warp.position - placed[feature.id]).norm());
    }
    std::printf("  placed features starting fine %d: %d of %zu kept over 3 frames, max error %.4f px\n", start_fine,
                tracker.NumFeatures(), placed.size(), max_error);
    if (start_fine) {
      EXPECT_EQ(tracker.NumFeatures(), static_cast<int>(placed.size()));
      EXPECT_LT(max_error, 0.1);
    } else {
      EXPECT_LE(tracker.NumFeatures(), static_cast<int>(0.75 * placed.size()));
    }
  }
}

}  // namespace
}  // namespace retrace
