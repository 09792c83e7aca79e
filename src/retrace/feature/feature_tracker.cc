#include "retrace/feature/feature_tracker.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace retrace {
namespace {

// Smallest accepted eigenvalue per window pixel of the geometric Gauss-Newton block once the contrast
// parameters are projected out ((grey levels / pixel)^2): below it the window is too flat to be aligned.
constexpr double kMinEigenvaluePerPixel = 0.05;
// Smallest accepted standard deviation of a reference window (grey levels).
constexpr double kMinStdDev = 0.5;
// Alignment stops early at level 0 when the RMS residual is still above this multiple of R after 3
// iterations.
constexpr double kGiveUpResidualFactor = 3.0;
// Largest window size supported by the stack buffers of the alignment.
constexpr int kMaxWindowSize = 63;

// Bilinear sample of a CV_32FC1 image; the caller guarantees 0 <= x < cols - 1 and 0 <= y < rows - 1.
inline float SampleBilinear(const cv::Mat& image, double x, double y) {
  const int ix = static_cast<int>(x), iy = static_cast<int>(y);
  const float fx = static_cast<float>(x - ix), fy = static_cast<float>(y - iy);
  const float* r0 = image.ptr<float>(iy) + ix;
  const float* r1 = image.ptr<float>(iy + 1) + ix;
  const float top = r0[0] + fx * (r0[1] - r0[0]);
  const float bottom = r1[0] + fx * (r1[1] - r1[0]);
  return top + fy * (bottom - top);
}

// Keys cubic convolution weights (a = -0.5) of the four samples floor(x) - 1 .. floor(x) + 2 at fraction f.
inline void CubicWeights(float f, float* w) {
  const float f2 = f * f, f3 = f2 * f;
  w[0] = -0.5f * f3 + f2 - 0.5f * f;
  w[1] = 1.5f * f3 - 2.5f * f2 + 1.0f;
  w[2] = -1.5f * f3 + 2.0f * f2 + 0.5f * f;
  w[3] = 0.5f * f3 - 0.5f * f2;
}

// Samples the window x = (dx, dy) + scale * u (u integer offsets in [-half, half]^2) of a CV_32FC1 image into
// `out` (row-major w*w), bilinearly. The caller checks that the samples are inside the image.
void SampleWindowBilinear(const cv::Mat& image, double dx, double dy, double scale, int w, float* out) {
  const int half = w / 2;
  int ix[kMaxWindowSize], iy[kMaxWindowSize];
  float fx[kMaxWindowSize], fy[kMaxWindowSize];
  for (int k = 0; k < w; ++k) {
    const double x = dx + scale * (k - half), y = dy + scale * (k - half);
    ix[k] = static_cast<int>(x);
    iy[k] = static_cast<int>(y);
    fx[k] = static_cast<float>(x - ix[k]);
    fy[k] = static_cast<float>(y - iy[k]);
  }
  const size_t stride = image.step1();
  const float* base = image.ptr<float>(0);
  for (int r = 0; r < w; ++r) {
    const float* row0 = base + iy[r] * stride;
    const float* row1 = row0 + stride;
    const float wy = fy[r];
    float* o = out + r * w;
    for (int c = 0; c < w; ++c) {
      const int i = ix[c];
      const float top = row0[i] + fx[c] * (row0[i + 1] - row0[i]);
      const float bottom = row1[i] + fx[c] * (row1[i + 1] - row1[i]);
      o[c] = top + wy * (bottom - top);
    }
  }
}

// The same with separable cubic interpolation: the warp is axis-aligned, so every image row touched is
// filtered horizontally once at the w sample columns, then the rows are combined vertically. Bilinear
// interpolation blurs by an amount that depends on the sub-pixel phase, which biases the scale and the
// position by several hundredths of a pixel; cubic interpolation removes most of it.
void SampleWindowCubic(const cv::Mat& image, double dx, double dy, double scale, int w, float* out) {
  const int half = w / 2;
  int ix[kMaxWindowSize], iy[kMaxWindowSize];
  float wx[kMaxWindowSize][4], wy[kMaxWindowSize][4];
  for (int k = 0; k < w; ++k) {
    const double x = dx + scale * (k - half), y = dy + scale * (k - half);
    const int fx = static_cast<int>(x), fy = static_cast<int>(y);
    ix[k] = fx - 1;
    iy[k] = fy - 1;
    CubicWeights(static_cast<float>(x - fx), wx[k]);
    CubicWeights(static_cast<float>(y - fy), wy[k]);
  }
  const int row_min = iy[0];
  const int num_rows = iy[w - 1] + 4 - row_min;
  thread_local std::vector<float> rows;
  if (rows.size() < static_cast<size_t>(num_rows) * w) rows.resize(static_cast<size_t>(num_rows) * w);
  const size_t stride = image.step1();
  const float* base = image.ptr<float>(0);
  for (int r = 0; r < num_rows; ++r) {
    const float* row = base + (row_min + r) * stride;
    float* h = rows.data() + static_cast<size_t>(r) * w;
    for (int c = 0; c < w; ++c) {
      const float* p = row + ix[c];
      h[c] = wx[c][0] * p[0] + wx[c][1] * p[1] + wx[c][2] * p[2] + wx[c][3] * p[3];
    }
  }
  for (int r = 0; r < w; ++r) {
    const float* h0 = rows.data() + static_cast<size_t>(iy[r] - row_min) * w;
    const float* h1 = h0 + w;
    const float* h2 = h1 + w;
    const float* h3 = h2 + w;
    const float w0 = wy[r][0], w1 = wy[r][1], w2 = wy[r][2], w3 = wy[r][3];
    float* o = out + r * w;
    for (int c = 0; c < w; ++c) o[c] = w0 * h0[c] + w1 * h1[c] + w2 * h2[c] + w3 * h3[c];
  }
}

}  // namespace

bool AlignmentOptions::Check() const {
  return window_size >= 3 && window_size <= kMaxWindowSize && window_size % 2 == 1 &&
         max_iterations_coarse >= 0 && max_iterations_fine >= 1 && convergence_epsilon > 0.0 &&
         max_residual > 0.0 && min_scale > 0.0 && min_scale < 1.0 && max_scale > 1.0 && min_gain > 0.0 &&
         min_gain < 1.0 && max_gain > 1.0 && scale_prior_sigma >= 0.0 && max_block_residual > 0.0;
}

std::string TrackStatusName(TrackStatus status) {
  switch (status) {
    case TrackStatus::kTracked:
      return "tracked";
    case TrackStatus::kResidualTooLarge:
      return "residual too large";
    case TrackStatus::kNotConverged:
      return "not converged";
    case TrackStatus::kOutOfImage:
      return "out of image";
    case TrackStatus::kScaleOutOfRange:
      return "scale out of range";
    case TrackStatus::kGainOutOfRange:
      return "gain out of range";
    case TrackStatus::kFarFromPrediction:
      return "far from prediction";
    case TrackStatus::kDegenerate:
      return "degenerate";
  }
  return "unknown";
}

bool ReferencePatch::Create(const ImagePyramid& pyramid, const Vector2d& position, int window_size,
                            int max_levels) {
  num_levels_ = 0;
  if (window_size < 3 || window_size > kMaxWindowSize || window_size % 2 == 0 || pyramid.Empty())
    return false;
  window_size_ = window_size;
  position_ = position;
  const int half = window_size / 2;
  const int n = window_size * window_size;
  const int levels = std::min(max_levels, pyramid.NumLevels());
  data_.assign(static_cast<size_t>(std::max(levels, 0)) * 4 * n, 0.0f);
  inverse_hessian_.resize(std::max(levels, 0));
  inverse_hessian_translation_.resize(std::max(levels, 0));
  mean_.assign(std::max(levels, 0), 0.0);
  const int ext = window_size + 2;  // window plus a one-pixel border for the central-difference gradients
  std::vector<float> sampled(static_cast<size_t>(ext) * ext);
  for (int level = 0; level < levels; ++level) {
    const cv::Mat& image = pyramid.Level(level);
    const double to_level = std::ldexp(1.0, -level);
    const double px = position.x() * to_level, py = position.y() * to_level;
    if (!(px - half - 1 >= 0.0 && py - half - 1 >= 0.0 && px + half + 1 < image.cols - 1 &&
          py + half + 1 < image.rows - 1)) {
      break;
    }
    for (int r = 0; r < ext; ++r) {
      for (int c = 0; c < ext; ++c) {
        sampled[r * ext + c] = SampleBilinear(image, px + c - half - 1, py + r - half - 1);
      }
    }
    float* t = data_.data() + Offset(level);
    float* gx = t + n;
    float* gy = t + 2 * n;
    float* gs = t + 3 * n;
    Eigen::Matrix<double, 5, 5> hessian = Eigen::Matrix<double, 5, 5>::Zero();
    double sum = 0.0, sum_sq = 0.0;
    for (int r = 0; r < window_size; ++r) {
      for (int c = 0; c < window_size; ++c) {
        const int k = r * window_size + c;
        const float* s = &sampled[(r + 1) * ext + (c + 1)];
        t[k] = s[0];
        gx[k] = 0.5f * (s[1] - s[-1]);
        gy[k] = 0.5f * (s[ext] - s[-ext]);
        gs[k] = static_cast<float>(c - half) * gx[k] + static_cast<float>(r - half) * gy[k];
        sum += t[k];
        sum_sq += static_cast<double>(t[k]) * t[k];
      }
    }
    // Centre the values: the contrast columns (T - mean, 1) are then orthogonal and the normal equations well
    // conditioned in float.
    const double mean = sum / n;
    for (int k = 0; k < n; ++k) {
      t[k] = static_cast<float>(t[k] - mean);
      Eigen::Matrix<double, 5, 1> j;
      j << gx[k], gy[k], gs[k], t[k], 1.0;
      hessian.selfadjointView<Eigen::Lower>().rankUpdate(j);
    }
    hessian.triangularView<Eigen::StrictlyUpper>() = hessian.transpose();
    mean_[level] = mean;
    const double std_dev = std::sqrt(std::max(0.0, sum_sq / n - mean * mean));
    if (level == 0) std_dev_ = std_dev;
    if (std_dev < kMinStdDev) break;
    // Conditioning of the geometric parameters with the contrast parameters projected out (Schur complement).
    const Eigen::Matrix3d schur =
        hessian.topLeftCorner<3, 3>() - hessian.topRightCorner<3, 2>() *
                                            hessian.bottomRightCorner<2, 2>().inverse() *
                                            hessian.bottomLeftCorner<2, 3>();
    // Compare in units where the scale column is a corner displacement (scale step * half window).
    Eigen::Vector3d unit(1.0, 1.0, 1.0 / half);
    const Eigen::Matrix3d normalised = unit.asDiagonal() * schur * unit.asDiagonal();
    const double min_eigenvalue = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(normalised).eigenvalues()(0);
    if (!(min_eigenvalue / n > kMinEigenvaluePerPixel)) break;
    inverse_hessian_[level] = hessian.inverse().cast<float>();
    // Without the scale parameter (coarse levels): invert the 4x4 system of (dx, dy, lambda, delta).
    Eigen::Matrix4d reduced;
    const int keep[4] = {0, 1, 3, 4};
    for (int i = 0; i < 4; ++i) {
      for (int j = 0; j < 4; ++j) reduced(i, j) = hessian(keep[i], keep[j]);
    }
    const Eigen::Matrix4d reduced_inverse = reduced.inverse();
    Eigen::Matrix<float, 5, 5>& translation_only = inverse_hessian_translation_[level];
    translation_only.setZero();
    for (int i = 0; i < 4; ++i) {
      for (int j = 0; j < 4; ++j)
        translation_only(keep[i], keep[j]) = static_cast<float>(reduced_inverse(i, j));
    }
    num_levels_ = level + 1;
  }
  if (num_levels_ == 0) {
    data_.clear();
    inverse_hessian_.clear();
    inverse_hessian_translation_.clear();
    mean_.clear();
    return false;
  }
  data_.resize(Offset(num_levels_));
  inverse_hessian_.resize(num_levels_);
  inverse_hessian_translation_.resize(num_levels_);
  mean_.resize(num_levels_);
  return true;
}

AlignmentResult AlignToReference(const ImagePyramid& pyramid, const ReferencePatch& reference,
                                 const WarpState& initial, const AlignmentOptions& options) {
  AlignmentResult result;
  result.warp = initial;
  result.residual = std::numeric_limits<double>::infinity();
  if (!reference.Valid() || pyramid.Empty() || !(initial.gain > 0.0) || !(initial.scale > 0.0)) return result;
  const int w = reference.WindowSize();
  const int half = w / 2;
  const int n = w * w;
  const int coarsest = std::min(pyramid.NumLevels(), reference.NumLevels()) - 1;

  // Template-side contrast: I ~ lambda T + delta, i.e. alpha = 1 / lambda, beta = -delta / lambda.
  double lambda = 1.0 / initial.gain;
  double delta = -initial.bias / initial.gain;
  double scale = initial.scale;
  Vector2d position = initial.position;
  bool converged = false;
  double residual = std::numeric_limits<double>::infinity();

  // Weight of the scale prior in units of squared grey levels (residual noise of 1 grey level per pixel).
  const double scale_prior_weight =
      options.scale_prior_sigma > 0.0 ? 1.0 / (options.scale_prior_sigma * options.scale_prior_sigma) : 0.0;
  float values[kMaxWindowSize * kMaxWindowSize];
  bool contrast_initialised = false;

  for (int level = coarsest; level >= 0; --level) {
    const cv::Mat& image = pyramid.Level(level);
    const double to_level = std::ldexp(1.0, -level);
    double dx = position.x() * to_level, dy = position.y() * to_level;
    const bool fine = level == 0;
    const bool cubic = fine && options.cubic_interpolation;
    const int max_iterations = fine ? options.max_iterations_fine : options.max_iterations_coarse;
    const float* t = reference.Centered(level);
    const float* gx = reference.Gx(level);
    const float* gy = reference.Gy(level);
    const float* gs = reference.Gs(level);
    // Coarse levels estimate translation and contrast only (the scale is kept): with the scale free, coarse
    // windows far from the solution too easily shrink or grow onto a neighbouring structure.
    const bool estimate_scale = fine || !options.coarse_translation_only;
    const Eigen::Matrix<float, 5, 5>& inverse_hessian =
        estimate_scale ? reference.InverseHessian(level) : reference.InverseHessianTranslation(level);
    const double mean = reference.Mean(level);
    converged = false;
    for (int iteration = 0;; ++iteration) {
      if (!fine && iteration >= max_iterations) break;
      const double extent = scale * half;
      // Cubic sampling needs one more pixel on each side than bilinear sampling.
      const double margin = cubic ? 1.0 : 0.0;
      if (!(dx - extent >= margin && dy - extent >= margin && dx + extent < image.cols - 1 - margin &&
            dy + extent < image.rows - 1 - margin)) {
        if (!fine) break;  // the window does not fit on this coarse level: continue on the finer one
        result.status = TrackStatus::kOutOfImage;
        result.warp.position = Vector2d(dx, dy);
        result.warp.scale = scale;
        result.iterations += iteration;
        return result;
      }
      if (cubic) {
        SampleWindowCubic(image, dx, dy, scale, w, values);
      } else {
        SampleWindowBilinear(image, dx, dy, scale, w, values);
      }
      if (options.contrast_from_moments && !contrast_initialised) {
        // Start the contrast from the first two moments of the window: lambda = std(I) / std(T),
        // delta = mean(I) - lambda mean(T); robust to large gain and bias changes and cheap.
        contrast_initialised = true;
        double sum_i = 0.0, sum_ii = 0.0, sum_tt = 0.0;
        for (int k = 0; k < n; ++k) {
          sum_i += values[k];
          sum_ii += static_cast<double>(values[k]) * values[k];
          sum_tt += static_cast<double>(t[k]) * t[k];  // centred template
        }
        const double var_i = sum_ii / n - (sum_i / n) * (sum_i / n);
        const double var_t = sum_tt / n;
        if (var_i > 0.0 && var_t > 0.0) {
          lambda = std::clamp(std::sqrt(var_i / var_t), 1.0 / options.max_gain, 1.0 / options.min_gain);
          delta = sum_i / n - lambda * mean;
        }
      }
      // Error image and J0^T e (Segvic 2009 §4.2 warp; inverse compositional, see the header).
      const float lam = static_cast<float>(lambda), del = static_cast<float>(delta + lambda * mean);
      // Eight independent partial sums per quantity so that the compiler can keep them in SIMD registers
      // (float additions are not reassociated otherwise).
      constexpr int kLanes = 8;
      float acc[6][kLanes] = {};
      int k = 0;
      for (; k + kLanes <= n; k += kLanes) {
        for (int l = 0; l < kLanes; ++l) {
          const float e = values[k + l] - lam * t[k + l] - del;
          acc[0][l] += gx[k + l] * e;
          acc[1][l] += gy[k + l] * e;
          acc[2][l] += gs[k + l] * e;
          acc[3][l] += t[k + l] * e;
          acc[4][l] += e;
          acc[5][l] += e * e;
        }
      }
      for (; k < n; ++k) {
        const float e = values[k] - lam * t[k] - del;
        acc[0][0] += gx[k] * e;
        acc[1][0] += gy[k] * e;
        acc[2][0] += gs[k] * e;
        acc[3][0] += t[k] * e;
        acc[4][0] += e;
        acc[5][0] += e * e;
      }
      float sums[6];
      for (int q = 0; q < 6; ++q) {
        sums[q] = 0.f;
        for (int l = 0; l < kLanes; ++l) sums[q] += acc[q][l];
      }
      const float b0 = sums[0], b1 = sums[1], b2 = sums[2], b3 = sums[3], b4 = sums[4], sse = sums[5];
      if (fine && (converged || iteration >= max_iterations)) {
        residual = std::sqrt(sse / n) / lambda;
        // RMS residual of the worst of the 3x3 blocks of the window: an occluder over part of the window
        // shows there even when the whole-window RMS stays small.
        double block_sse[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
        int block_count[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
        for (int r = 0; r < w; ++r) {
          for (int c = 0; c < w; ++c) {
            const int k = r * w + c;
            const double e = values[k] - lam * t[k] - del;
            const int block = (r * 3 / w) * 3 + c * 3 / w;
            block_sse[block] += e * e;
            ++block_count[block];
          }
        }
        double worst = 0.0;
        for (int b = 0; b < 9; ++b) worst = std::max(worst, block_sse[b] / std::max(1, block_count[b]));
        result.block_residual = std::sqrt(worst) / lambda;
        result.iterations += iteration;
        break;
      }
      Eigen::Matrix<float, 5, 1> b;
      b << b0, b1, b2, b3, b4;
      if (fine && iteration >= 3 &&
          sse > n * kGiveUpResidualFactor * kGiveUpResidualFactor * options.max_residual *
                    options.max_residual * lambda * lambda) {
        // Still far above R after a few iterations at level 0: this window will not match (occlusion, wrong
        // basin); stop early instead of spending the remaining iterations.
        result.status = TrackStatus::kResidualTooLarge;
        result.residual = std::sqrt(sse / n) / lambda;
        result.warp.position = Vector2d(dx, dy);
        result.warp.scale = scale;
        result.iterations += iteration;
        return result;
      }
      const Eigen::Matrix<float, 5, 1> h0_step = inverse_hessian * b;
      // Gauss-Newton step of (dx, dy, ds, dlambda, ddelta): D^-1 H0^-1 J0^T e with D = diag(l, l, l, 1, 1).
      Eigen::Matrix<double, 5, 1> step;
      step << h0_step(0) / lambda, h0_step(1) / lambda, h0_step(2) / lambda, h0_step(3), h0_step(4);
      if (estimate_scale && scale_prior_weight > 0.0) {
        // Prior mu (log s' - log s0)^2 with s' ~ s (1 - ds): adds mu to the ds diagonal and mu (log s - log
        // s0) to its right-hand side; solved with the precomputed inverse by Sherman-Morrison.
        Eigen::Matrix<double, 5, 1> u;
        for (int i = 0; i < 5; ++i) u(i) = inverse_hessian(i, 2);
        u.head<3>() /= lambda;
        u /= lambda;  // u = A^-1 e2 with A = D H0 D
        const double a22 = inverse_hessian(2, 2) / (lambda * lambda);
        const double c = std::log(scale / initial.scale);
        const Eigen::Matrix<double, 5, 1> x0 = step + u * (scale_prior_weight * c);
        step = x0 - u * (scale_prior_weight * x0(2) / (1.0 + scale_prior_weight * a22));
      }
      const double step_x = step(0), step_y = step(1), step_s = step(2);
      if (!(1.0 + step_s > 0.5) || !std::isfinite(step_x) || !std::isfinite(step_y)) {
        result.status = TrackStatus::kNotConverged;
        result.iterations += iteration + 1;
        return result;
      }
      // Inverse composition of the geometric step, additive contrast step.
      const double new_scale = scale / (1.0 + step_s);
      const double new_dx = dx - scale * step_x / (1.0 + step_s);
      const double new_dy = dy - scale * step_y / (1.0 + step_s);
      const double corner_shift =
          std::hypot(new_dx - dx, new_dy - dy) + std::abs(new_scale - scale) * half * 1.4142135623730951;
      dx = new_dx;
      dy = new_dy;
      scale = new_scale;
      if (!(scale > 0.5 * options.min_scale && scale < 2.0 * options.max_scale)) {
        result.status = TrackStatus::kScaleOutOfRange;
        result.warp.scale = scale;
        result.iterations += iteration + 1;
        return result;
      }
      // Contrast step (on the offset of the centred template). Far from the solution (coarse levels, large
      // displacements) the contrast step can be wild; it is then skipped for this iteration, and the final
      // gain is checked against its range after convergence.
      const double new_lambda = lambda + step(3);
      if (new_lambda > 1.0 / options.max_gain && new_lambda < 1.0 / options.min_gain) {
        delta += step(4) - step(3) * mean;
        lambda = new_lambda;
      }
      converged = corner_shift < options.convergence_epsilon;
      if (!fine && converged) {
        result.iterations += iteration + 1;
        break;
      }
    }
    position = Vector2d(dx, dy) / to_level;
  }

  result.warp.position = position;
  result.warp.scale = scale;
  result.warp.gain = 1.0 / lambda;
  result.warp.bias = -delta / lambda;
  result.residual = residual;
  result.converged = converged;
  if (scale < options.min_scale || scale > options.max_scale) {
    result.status = TrackStatus::kScaleOutOfRange;
  } else if (result.warp.gain < options.min_gain || result.warp.gain > options.max_gain) {
    result.status = TrackStatus::kGainOutOfRange;
  } else if (!converged) {
    result.status = TrackStatus::kNotConverged;
  } else if (!(residual <= options.max_residual) || !(result.block_residual <= options.max_block_residual)) {
    result.status = TrackStatus::kResidualTooLarge;
  } else {
    result.status = TrackStatus::kTracked;
  }
  return result;
}

AlignmentResult RefinePrediction(const ImagePyramid& pyramid, const ReferencePatch& reference,
                                 const Vector2d& predicted_position, double initial_scale,
                                 const RefinePredictionOptions& options) {
  WarpState initial;
  initial.position = predicted_position;
  initial.scale = initial_scale;
  AlignmentResult result = AlignToReference(pyramid, reference, initial, options.alignment);
  if (!result.ok()) return result;
  const double ratio = result.warp.scale / initial_scale;
  if ((result.warp.position - predicted_position).norm() > options.max_distance ||
      ratio > options.max_scale_ratio || ratio < 1.0 / options.max_scale_ratio) {
    result.status = TrackStatus::kFarFromPrediction;
  }
  return result;
}

FeatureTracker::FeatureTracker(const FeatureTrackerOptions& options) : options_(options) {
  if (!options_.Check()) throw std::invalid_argument("FeatureTracker: invalid options");
}

feature_t FeatureTracker::AddFeature(const ImagePyramid& pyramid, const Vector2d& position, feature_t id) {
  ReferencePatch reference;
  if (!reference.Create(pyramid, position, options_.alignment.window_size, options_.num_levels)) {
    return kInvalidFeatureId;
  }
  AlignmentResult alignment;
  alignment.warp.position = position;
  alignment.residual = 0.0;
  alignment.converged = true;
  alignment.status = TrackStatus::kTracked;
  return AddFeature(reference, alignment, id);
}

std::vector<feature_t> FeatureTracker::AddFeatures(const ImagePyramid& pyramid,
                                                   const std::vector<Vector2d>& positions) {
  std::vector<feature_t> ids;
  ids.reserve(positions.size());
  for (const Vector2d& p : positions) ids.push_back(AddFeature(pyramid, p));
  return ids;
}

feature_t FeatureTracker::AddFeature(const ReferencePatch& reference, const AlignmentResult& alignment,
                                     feature_t id) {
  if (!reference.Valid() || reference.WindowSize() != options_.alignment.window_size)
    return kInvalidFeatureId;
  if (id == kInvalidFeatureId) id = next_id_;
  if (IndexOf(id) >= 0) return kInvalidFeatureId;
  next_id_ = std::max(next_id_, id + 1);
  TrackedFeature feature;
  feature.id = id;
  feature.warp = alignment.warp;
  feature.residual = alignment.residual;
  feature.converged = alignment.converged;
  feature.status = TrackStatus::kTracked;
  feature.num_frames = 1;
  features_.push_back(feature);
  references_.push_back(reference);
  velocities_.push_back(Vector2d::Zero());
  return id;
}

const std::vector<TrackedFeature>& FeatureTracker::Track(const ImagePyramid& pyramid) {
  last_results_.clear();
  std::vector<AlignmentResult>& results = scratch_results_;
  results.assign(features_.size(), AlignmentResult());
  const auto align = [&](size_t i, const Vector2d& velocity) {
    const TrackedFeature& feature = features_[i];
    WarpState initial = feature.warp;
    const bool predicted = velocity.squaredNorm() > 0.25;
    if (predicted) initial.position += velocity;
    results[i] = AlignToReference(pyramid, references_[i], initial, options_.alignment);
    if (!results[i].ok() && predicted) {
      // The guess may be wrong after an abrupt change of motion: retry from the last position.
      AlignmentResult retry = AlignToReference(pyramid, references_[i], feature.warp, options_.alignment);
      if (retry.ok()) results[i] = retry;
    }
  };
  // Features with a velocity go first (constant-velocity guess). Features without one (new, or with a motion too
  // small to tell) start from the median displacement of the others in this frame: the image motion of a moving
  // camera is coherent enough for a first guess, and it matters in turns, where displacements are large.
  std::vector<double>& dx = scratch_dx_;
  std::vector<double>& dy = scratch_dy_;
  std::vector<size_t>& without_velocity = scratch_without_velocity_;
  dx.clear();
  dy.clear();
  without_velocity.clear();
  for (size_t i = 0; i < features_.size(); ++i) {
    if (!options_.constant_velocity || velocities_[i].squaredNorm() <= 0.25) {
      without_velocity.push_back(i);
      continue;
    }
    align(i, velocities_[i]);
    if (results[i].ok()) {
      dx.push_back(results[i].warp.position.x() - features_[i].warp.position.x());
      dy.push_back(results[i].warp.position.y() - features_[i].warp.position.y());
    }
  }
  Vector2d common_motion = Vector2d::Zero();
  if (options_.constant_velocity && dx.size() >= 5) {
    std::nth_element(dx.begin(), dx.begin() + dx.size() / 2, dx.end());
    std::nth_element(dy.begin(), dy.begin() + dy.size() / 2, dy.end());
    common_motion = Vector2d(dx[dx.size() / 2], dy[dy.size() / 2]);
  }
  for (size_t i : without_velocity) align(i, common_motion);

  size_t kept = 0;
  for (size_t i = 0; i < features_.size(); ++i) {
    const AlignmentResult& result = results[i];
    TrackedFeature updated = features_[i];
    const Vector2d previous_position = updated.warp.position;
    updated.warp = result.warp;
    updated.residual = result.residual;
    updated.block_residual = result.block_residual;
    updated.converged = result.converged;
    updated.status = result.status;
    if (result.ok()) {
      updated.num_frames += 1;
      velocities_[kept] = result.warp.position - previous_position;
      features_[kept] = updated;
      if (kept != i) references_[kept] = std::move(references_[i]);
      ++kept;
    }
    last_results_.push_back(updated);
  }
  features_.resize(kept);
  references_.resize(kept);
  velocities_.resize(kept);
  return last_results_;
}

bool FeatureTracker::Remove(feature_t id) {
  const int index = IndexOf(id);
  if (index < 0) return false;
  features_.erase(features_.begin() + index);
  references_.erase(references_.begin() + index);
  velocities_.erase(velocities_.begin() + index);
  return true;
}

bool FeatureTracker::SetReference(feature_t id, const ImagePyramid& pyramid, const Vector2d& position) {
  const int index = IndexOf(id);
  if (index < 0) return false;
  ReferencePatch reference;
  if (!reference.Create(pyramid, position, options_.alignment.window_size, options_.num_levels)) return false;
  references_[index] = std::move(reference);
  TrackedFeature& feature = features_[index];
  feature.warp = WarpState();
  feature.warp.position = position;
  feature.residual = 0.0;
  // The velocity is kept: it belongs to the motion of the camera, not to the reference.
  return true;
}

const TrackedFeature* FeatureTracker::Find(feature_t id) const {
  const int index = IndexOf(id);
  return index < 0 ? nullptr : &features_[index];
}

const ReferencePatch* FeatureTracker::Reference(feature_t id) const {
  const int index = IndexOf(id);
  return index < 0 ? nullptr : &references_[index];
}

int FeatureTracker::IndexOf(feature_t id) const {
  for (size_t i = 0; i < features_.size(); ++i) {
    if (features_[i].id == id) return static_cast<int>(i);
  }
  return -1;
}

}  // namespace retrace
