#include "retrace/image/perturbation.h"

#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

namespace retrace {
namespace {

// Uniform random levels in [lo, hi) from a fixed seed.
cv::Mat RandomImage(int lo, int hi, cv::Size size = cv::Size(320, 240)) {
  cv::Mat image(size, CV_8UC1);
  cv::RNG rng(12345);
  rng.fill(image, cv::RNG::UNIFORM, lo, hi);
  return image;
}

TEST(Perturbation, IdentityLeavesImageUnchanged) {
  const cv::Mat image = RandomImage(0, 256);
  PerturbationOptions options;
  EXPECT_TRUE(options.Check());
  EXPECT_TRUE(options.IsIdentity());
  EXPECT_EQ(cv::norm(PerturbImage(image, 3, options), image, cv::NORM_INF), 0.0);
}

TEST(Perturbation, BrightnessGammaContrast) {
  const cv::Mat image = RandomImage(20, 200);
  const double mean_in = cv::mean(image)[0];
  PerturbationOptions options;
  options.brightness = 0.6;
  const double ratio = cv::mean(PerturbImage(image, 0, options))[0] / mean_in;
  EXPECT_NEAR(ratio, 0.6, 0.005) << "measured mean brightness ratio " << ratio;

  // With gamma: compare with the model 255 a (v/255)^g averaged over the input.
  options.gamma = 1.4;
  cv::Mat v;
  image.convertTo(v, CV_64F, 1.0 / 255.0);
  cv::pow(v, 1.4, v);
  const double expected = 255.0 * 0.6 * cv::mean(v)[0];
  const double measured = cv::mean(PerturbImage(image, 0, options))[0];
  EXPECT_NEAR(measured, expected, 0.3);
  EXPECT_LT(measured, 0.6 * mean_in);  // gamma > 1 darkens further

  // Contrast 0.5 halves the standard deviation about mid-grey (no clamping in this range).
  PerturbationOptions contrast;
  contrast.contrast = 0.5;
  cv::Scalar mean_a, std_a, mean_b, std_b;
  cv::meanStdDev(image, mean_a, std_a);
  cv::meanStdDev(PerturbImage(image, 0, contrast), mean_b, std_b);
  EXPECT_NEAR(std_b[0] / std_a[0], 0.5, 0.01);
  EXPECT_NEAR(mean_b[0], 127.5 + 0.5 * (mean_a[0] - 127.5), 0.3);
}

TEST(Perturbation, NoiseHasRequestedSigmaAndIsSeeded) {
  const cv::Mat flat(240, 320, CV_8UC1, cv::Scalar(128));
  PerturbationOptions options;
  options.noise_sigma = 6.0;
  options.seed = 7;
  const cv::Mat a = PerturbImage(flat, 10, options);
  cv::Scalar mean, stddev;
  cv::meanStdDev(a, mean, stddev);
  EXPECT_NEAR(mean[0], 128.0, 0.1);
  // Rounding adds a variance of 1/12: sqrt(36 + 1/12) = 6.007.
  EXPECT_NEAR(stddev[0], 6.0, 0.1) << "measured noise std " << stddev[0];
  // Deterministic: same seed and frame -> identical; another frame or seed -> different.
  EXPECT_EQ(cv::norm(a, PerturbImage(flat, 10, options), cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a, PerturbImage(flat, 11, options), cv::NORM_L1), 0.0);
  options.seed = 8;
  EXPECT_GT(cv::norm(a, PerturbImage(flat, 10, options), cv::NORM_L1), 0.0);
}

TEST(Perturbation, BlurFollowsGaussianEdgeProfile) {
  // Vertical step between columns 49 and 50: after blurring, column 50 + k lies at k + 0.5 pixels from the edge and
  // has the value 255 * Phi((k + 0.5) / sigma).
  cv::Mat step(40, 100, CV_8UC1, cv::Scalar(0));
  step.colRange(50, 100).setTo(255);
  PerturbationOptions options;
  options.blur_sigma = 2.0;
  const cv::Mat blurred = PerturbImage(step, 0, options);
  const auto phi = [](double x) { return 0.5 * std::erfc(-x / std::sqrt(2.0)); };
  for (int k = -4; k <= 4; ++k) {
    const double expected = 255.0 * phi((k + 0.5) / 2.0);
    EXPECT_NEAR(blurred.at<uint8_t>(20, 50 + k), expected, 2.5) << "k = " << k;
  }
}

TEST(Perturbation, OccluderCoversFractionInRequestedFramesAndMoves) {
  const cv::Mat flat(240, 320, CV_8UC1, cv::Scalar(128));
  PerturbationOptions options;
  options.occluder_fraction = 0.4;
  options.occluder_first_frame = 40;
  options.occluder_last_frame = 50;
  options.occluder_textured = false;
  options.occluder_gray = 0;
  options.seed = 3;
  int previous_x = -1;
  for (int frame = 35; frame <= 55; ++frame) {
    const cv::Mat out = PerturbImage(flat, frame, options);
    const double covered = 1.0 - cv::countNonZero(out) / static_cast<double>(out.total());
    if (frame < 40 || frame > 50) {
      EXPECT_EQ(covered, 0.0) << "frame " << frame;
      continue;
    }
    EXPECT_NEAR(covered, 0.4, 0.005) << "frame " << frame;
    const cv::Rect rect = OccluderRect(out.size(), frame, options);
    EXPECT_EQ(cv::countNonZero(out(rect)), 0);
    EXPECT_GT(rect.x, previous_x);  // moves to the right every frame
    previous_x = rect.x;
    if (frame == 40) {
      EXPECT_EQ(rect.x, 0);
    }
    if (frame == 50) {
      EXPECT_EQ(rect.br().x, 320);
    }
  }

  // Textured: changes (nearly) only pixels inside its rectangle, the same texture for the same seed.
  options.occluder_textured = true;
  const cv::Mat textured = PerturbImage(flat, 45, options);
  const cv::Rect rect = OccluderRect(flat.size(), 45, options);
  cv::Mat changed = textured != flat;
  EXPECT_EQ(cv::countNonZero(changed) - cv::countNonZero(changed(rect)), 0);
  EXPECT_GT(cv::countNonZero(changed(rect)), 0.95 * rect.area());
  EXPECT_EQ(cv::norm(textured, PerturbImage(flat, 45, options), cv::NORM_INF), 0.0);
  options.seed = 4;
  EXPECT_GT(cv::norm(textured, PerturbImage(flat, 45, options), cv::NORM_L1), 0.0);
}

TEST(Perturbation, CheckRejectsInvalidOptions) {
  std::string error;
  PerturbationOptions options;
  options.gamma = 0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_EQ(error, "gamma must be > 0");
  options = PerturbationOptions();
  options.occluder_fraction = 1.0;
  EXPECT_FALSE(options.Check(&error));
  options = PerturbationOptions();
  options.noise_sigma = -1;
  EXPECT_FALSE(options.Check(&error));
}

}  // namespace
}  // namespace retrace
