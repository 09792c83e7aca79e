#include "retrace/feature/feature_tracker.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <stdexcept>

#if defined(__SSE2__)
#include <emmintrin.h>
#include <xmmintrin.h>
#endif

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
// The final refinement on the wide window stops early when its RMS residual is still above this multiple of R
// after 2 iterations.
constexpr double kWideGiveUpResidualFactor = 1.5;
// The affine fallback follows an alignment that converged with its RMS residual above R but at most this multiple
// of R (above it, 6 % of the adoptions for a third of the attempts on the simulated benchmark drive), and stops early
// when its own RMS residual is still above that after 2 iterations.
constexpr double kAffineResidualFactor = 1.5;
// Largest window size supported by the stack buffers of the alignment.
constexpr int kMaxWindowSize = 63;
// Largest sample spacing of the window of the final refinement.
constexpr int kMaxScaleWindowStride = 3;
// Largest side of a sampled grid (the dense grid from which a strided reference window is cut).
constexpr int kMaxSampledSide = (kMaxWindowSize - 1) * kMaxScaleWindowStride + 3;

// Keys cubic convolution weights (a = -0.5) of the four samples floor(x) - 1 .. floor(x) + 2 at fraction f.
inline void CubicWeights(float f, float* w) {
  const float f2 = f * f, f3 = f2 * f;
  w[0] = -0.5f * f3 + f2 - 0.5f * f;
  w[1] = 1.5f * f3 - 2.5f * f2 + 1.0f;
  w[2] = -1.5f * f3 + 2.0f * f2 + 0.5f * f;
  w[3] = 0.5f * f3 - 0.5f * f2;
}

// Calls group(c) for groups of four columns c .. c + 3 covering [0, w), w >= 4: the last group ends at column w - 1 and
// overlaps the one before when w is not a multiple of 4 (those columns are written twice, with the same values).
template <typename Group>
inline void ForGroupsOfFour(int w, Group&& group) {
  for (int c = 0; c < w - 4; c += 4) group(c);
  group(w - 4);
}

// Samples the window x = (dx, dy) + scale * u (u integer offsets in [-half, half]^2) of a CV_32FC1 image into
// `out` (row-major w*w), bilinearly. The caller checks that the samples are inside the image. Separable: the
// warp is axis-aligned, so every image row touched is interpolated once at the w sample columns, then the rows
// are combined vertically.
void SampleWindowBilinear(const cv::Mat& image, double dx, double dy, double scale, int w, float* out) {
  const int half = w / 2;
  // Columns padded to a multiple of 4 (the padding columns repeat the last one with zero weights).
  const int w4 = (w + 3) & ~3;
  int ix[kMaxSampledSide + 3], iy[kMaxSampledSide];
  alignas(16) float wx[kMaxSampledSide + 3][2];
  float fy[kMaxSampledSide];
  for (int k = 0; k < w; ++k) {
    const double x = dx + scale * (k - half), y = dy + scale * (k - half);
    ix[k] = static_cast<int>(x);
    iy[k] = static_cast<int>(y);
    const float fx = static_cast<float>(x - ix[k]);
    wx[k][0] = 1.0f - fx;
    wx[k][1] = fx;
    fy[k] = static_cast<float>(y - iy[k]);
  }
  for (int k = w; k < w4; ++k) {
    ix[k] = ix[w - 1];
    wx[k][0] = wx[k][1] = 0.0f;
  }
  const int row_min = iy[0];
  const int num_rows = iy[w - 1] + 2 - row_min;
  thread_local std::vector<float> rows;
  if (rows.size() < static_cast<size_t>(num_rows) * w4) rows.resize(static_cast<size_t>(num_rows) * w4);
  const size_t stride = image.step1();
  const float* base = image.ptr<float>(0);
  for (int r = 0; r < num_rows; ++r) {
    const float* row = base + (row_min + r) * stride;
    float* h = rows.data() + static_cast<size_t>(r) * w4;
#if defined(__SSE2__)
    // Four output columns at a time: the two taps of two columns in one register, multiplied by their
    // weights, then the even and odd lanes added.
    for (int c = 0; c < w4; c += 4) {
      __m128 a = _mm_loadl_pi(_mm_setzero_ps(), reinterpret_cast<const __m64*>(row + ix[c]));
      a = _mm_loadh_pi(a, reinterpret_cast<const __m64*>(row + ix[c + 1]));
      __m128 b = _mm_loadl_pi(_mm_setzero_ps(), reinterpret_cast<const __m64*>(row + ix[c + 2]));
      b = _mm_loadh_pi(b, reinterpret_cast<const __m64*>(row + ix[c + 3]));
      a = _mm_mul_ps(a, _mm_load_ps(wx[c]));
      b = _mm_mul_ps(b, _mm_load_ps(wx[c + 2]));
      _mm_storeu_ps(h + c, _mm_add_ps(_mm_shuffle_ps(a, b, _MM_SHUFFLE(2, 0, 2, 0)),
                                      _mm_shuffle_ps(a, b, _MM_SHUFFLE(3, 1, 3, 1))));
    }
#else
    for (int c = 0; c < w4; ++c) h[c] = wx[c][0] * row[ix[c]] + wx[c][1] * row[ix[c] + 1];
#endif
  }
  for (int r = 0; r < w; ++r) {
    const float* h0 = rows.data() + static_cast<size_t>(iy[r] - row_min) * w4;
    const float* h1 = h0 + w4;
    const float f = fy[r];
    float* o = out + r * w;
#if defined(__SSE2__)
    // Four columns at a time, with the scalar loop's operations in its order (the same floats).
    if (w >= 4) {
      const __m128 vf = _mm_set1_ps(f);
      ForGroupsOfFour(w, [&](int c) {
        const __m128 a = _mm_loadu_ps(h0 + c);
        _mm_storeu_ps(o + c, _mm_add_ps(a, _mm_mul_ps(vf, _mm_sub_ps(_mm_loadu_ps(h1 + c), a))));
      });
      continue;
    }
#endif
    for (int c = 0; c < w; ++c) o[c] = h0[c] + f * (h1[c] - h0[c]);
  }
}

// The same with separable cubic interpolation: the warp is axis-aligned, so every image row touched is
// filtered horizontally once at the w sample columns, then the rows are combined vertically. Bilinear
// interpolation blurs by an amount that depends on the sub-pixel phase, which biases the scale and the
// position by several hundredths of a pixel; cubic interpolation removes most of it.
// `image` may be a copied part of the image sampled: its pixel (0, 0) is then the image's (origin_x, origin_y), and
// (dx, dy) are still the whole image's coordinates (the positions and weights are those of the whole image).
void SampleWindowCubic(const cv::Mat& image, double dx, double dy, double scale, int w, float* out, int origin_x = 0,
                       int origin_y = 0) {
  const int half = w / 2;
  // Columns padded to a multiple of 4 (the padding columns repeat the last one with zero weights).
  const int w4 = (w + 3) & ~3;
  int ix[kMaxSampledSide + 3], iy[kMaxSampledSide];
  alignas(16) float wx[kMaxSampledSide + 3][4];
  float wy[kMaxSampledSide][4];
  for (int k = 0; k < w; ++k) {
    const double x = dx + scale * (k - half), y = dy + scale * (k - half);
    const int fx = static_cast<int>(x), fy = static_cast<int>(y);
    ix[k] = fx - 1 - origin_x;
    iy[k] = fy - 1 - origin_y;
    CubicWeights(static_cast<float>(x - fx), wx[k]);
    CubicWeights(static_cast<float>(y - fy), wy[k]);
  }
  for (int k = w; k < w4; ++k) {
    ix[k] = ix[w - 1];
    wx[k][0] = wx[k][1] = wx[k][2] = wx[k][3] = 0.0f;
  }
  const int row_min = iy[0];
  const int num_rows = iy[w - 1] + 4 - row_min;
  thread_local std::vector<float> rows;
  if (rows.size() < static_cast<size_t>(num_rows) * w4) rows.resize(static_cast<size_t>(num_rows) * w4);
  const size_t stride = image.step1();
  const float* base = image.ptr<float>(0);
  for (int r = 0; r < num_rows; ++r) {
    const float* row = base + (row_min + r) * stride;
    float* h = rows.data() + static_cast<size_t>(r) * w4;
#if defined(__SSE2__)
    // Four output columns at a time: the four taps of each are one unaligned load, multiplied by its weights;
    // a 4x4 transpose turns the four dot products into one vertical sum.
    for (int c = 0; c < w4; c += 4) {
      __m128 a0 = _mm_mul_ps(_mm_loadu_ps(row + ix[c]), _mm_load_ps(wx[c]));
      __m128 a1 = _mm_mul_ps(_mm_loadu_ps(row + ix[c + 1]), _mm_load_ps(wx[c + 1]));
      __m128 a2 = _mm_mul_ps(_mm_loadu_ps(row + ix[c + 2]), _mm_load_ps(wx[c + 2]));
      __m128 a3 = _mm_mul_ps(_mm_loadu_ps(row + ix[c + 3]), _mm_load_ps(wx[c + 3]));
      _MM_TRANSPOSE4_PS(a0, a1, a2, a3);
      _mm_storeu_ps(h + c, _mm_add_ps(_mm_add_ps(a0, a1), _mm_add_ps(a2, a3)));
    }
#else
    for (int c = 0; c < w4; ++c) {
      const float* p = row + ix[c];
      h[c] = wx[c][0] * p[0] + wx[c][1] * p[1] + wx[c][2] * p[2] + wx[c][3] * p[3];
    }
#endif
  }
  for (int r = 0; r < w; ++r) {
    const float* h0 = rows.data() + static_cast<size_t>(iy[r] - row_min) * w4;
    const float* h1 = h0 + w4;
    const float* h2 = h1 + w4;
    const float* h3 = h2 + w4;
    const float w0 = wy[r][0], w1 = wy[r][1], w2 = wy[r][2], w3 = wy[r][3];
    float* o = out + r * w;
#if defined(__SSE2__)
    // Four columns at a time (the same floats as the scalar loop).
    if (w >= 4) {
      const __m128 v0 = _mm_set1_ps(w0), v1 = _mm_set1_ps(w1), v2 = _mm_set1_ps(w2), v3 = _mm_set1_ps(w3);
      ForGroupsOfFour(w, [&](int c) {
        __m128 sum = _mm_add_ps(_mm_mul_ps(v0, _mm_loadu_ps(h0 + c)), _mm_mul_ps(v1, _mm_loadu_ps(h1 + c)));
        sum = _mm_add_ps(sum, _mm_mul_ps(v2, _mm_loadu_ps(h2 + c)));
        _mm_storeu_ps(o + c, _mm_add_ps(sum, _mm_mul_ps(v3, _mm_loadu_ps(h3 + c))));
      });
      continue;
    }
#endif
    for (int c = 0; c < w; ++c) o[c] = w0 * h0[c] + w1 * h1[c] + w2 * h2[c] + w3 * h3[c];
  }
}

}  // namespace

bool AlignmentOptions::Check() const {
  return window_size >= 3 && window_size <= kMaxWindowSize && window_size % 2 == 1 && max_iterations_coarse >= 0 &&
         max_iterations_fine >= 1 && convergence_epsilon > 0.0 && max_residual > 0.0 && min_scale > 0.0 &&
         min_scale < 1.0 && max_scale > 1.0 && min_gain > 0.0 && min_gain < 1.0 && max_gain > 1.0 &&
         scale_prior_sigma >= 0.0 && max_block_residual > 0.0 && convergence_epsilon_coarse > 0.0 &&
         max_scale_window_shift > 0.0 && scale_window_stride >= 0 && scale_window_stride <= kMaxScaleWindowStride &&
         max_iterations_scale_window >= 1 && max_affine_anisotropy >= 1.0 && max_affine_shift > 0.0 &&
         max_iterations_affine >= 1 && convergence_epsilon_affine > 0.0 && robust_min_inlier_fraction > 0.0 &&
         robust_min_inlier_fraction <= 1.0 && robust_min_information_share >= 0.0 &&
         robust_min_information_share <= 1.0 && robust_threshold_factor >= 1.0;
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

namespace {

// Cuts a `w` x `w` window centred at (px, py) of `image` (one level) and fills `data` (centred values, Tx,
// Ty, u.grad T; w^2 floats each). Sampling is cubic when `cubic` (level 0: a reference cut at a sub-pixel
// position is then not blurred by a phase-dependent amount, which would bias the scale), bilinear otherwise.
// Returns false when the window does not fit or is too flat; otherwise sets the mean, standard deviation and
// the inverse Gauss-Newton matrices (full and without the scale). With `part` (cubic only), `image` is the part of
// an image of that size starting at `part->origin` (WindowPart): the same window as from the whole image.
struct WindowPart {
  cv::Point origin;
  cv::Size image_size;
};

// The side of the dense grid CutWindow samples: the window at `stride` plus a one-pixel border for the
// central-difference gradients.
int SampledSide(int w, int stride) { return (w - 1) * stride + 3; }

// Whether the window of CutWindow fits in an image of `size`.
bool WindowFitsImage(cv::Size size, double px, double py, int w, int stride, bool cubic) {
  const int ext_half = SampledSide(w, stride) / 2;
  const double margin = cubic ? 1.0 : 0.0;
  return px - ext_half - margin >= 0.0 && py - ext_half - margin >= 0.0 && px + ext_half + margin < size.width - 1 &&
         py + ext_half + margin < size.height - 1;
}

bool CutWindow(const cv::Mat& image, double px, double py, int w, int stride, bool cubic, float* data, double* mean_out,
               double* std_dev_out, Eigen::Matrix<float, 5, 5>* inverse_hessian,
               Eigen::Matrix<float, 5, 5>* inverse_hessian_translation, const WindowPart* part = nullptr) {
  const int half = w / 2;
  const int n = w * w;
  const int ext = SampledSide(w, stride);
  if (!WindowFitsImage(part != nullptr ? part->image_size : image.size(), px, py, w, stride, cubic)) return false;
  thread_local std::vector<float> sampled;
  sampled.resize(static_cast<size_t>(ext) * ext);
  if (cubic) {
    const cv::Point origin = part != nullptr ? part->origin : cv::Point(0, 0);
    SampleWindowCubic(image, px, py, 1.0, ext, sampled.data(), origin.x, origin.y);
  } else {
    SampleWindowBilinear(image, px, py, 1.0, ext, sampled.data());
  }
  float* t = data;
  float* gx = t + n;
  float* gy = t + 2 * n;
  float* gs = t + 3 * n;
  double sum = 0.0, sum_sq = 0.0;
  for (int r = 0; r < w; ++r) {
    for (int c = 0; c < w; ++c) {
      const int k = r * w + c;
      const float* s = &sampled[(r * stride + 1) * ext + (c * stride + 1)];
      t[k] = s[0];
      gx[k] = 0.5f * (s[1] - s[-1]);
      gy[k] = 0.5f * (s[ext] - s[-ext]);
      // u.grad T with u the offset in reference pixels.
      gs[k] = static_cast<float>((c - half) * stride) * gx[k] + static_cast<float>((r - half) * stride) * gy[k];
      sum += t[k];
      sum_sq += static_cast<double>(t[k]) * t[k];
    }
  }
  // Centre the values: the contrast columns (T - mean, 1) are then orthogonal and the normal equations well
  // conditioned in float.
  const double mean = sum / n;
  // H = Σ J0ᵀ J0 with J0 = [Tx, Ty, u.grad T, T, 1]: its 15 distinct sums, in two passes of few accumulators each
  // (they stay in registers).
  double xx = 0, xy = 0, xs = 0, x1 = 0, yy = 0, ys = 0, y1 = 0, ss = 0, s1 = 0;
  for (int k = 0; k < n; ++k) {
    const double jx = gx[k], jy = gy[k], js = gs[k];
    xx += jx * jx;
    xy += jx * jy;
    xs += jx * js;
    x1 += jx;
    yy += jy * jy;
    ys += jy * js;
    y1 += jy;
    ss += js * js;
    s1 += js;
  }
  double xt = 0, yt = 0, st = 0, tt = 0, t1 = 0;
  for (int k = 0; k < n; ++k) {
    t[k] = static_cast<float>(t[k] - mean);
    const double jt = t[k];
    xt += gx[k] * jt;
    yt += gy[k] * jt;
    st += gs[k] * jt;
    tt += jt * jt;
    t1 += jt;
  }
  Eigen::Matrix<double, 5, 5> hessian;
  hessian << xx, xy, xs, xt, x1,  //
      xy, yy, ys, yt, y1,         //
      xs, ys, ss, st, s1,         //
      xt, yt, st, tt, t1,         //
      x1, y1, s1, t1, static_cast<double>(n);
  *mean_out = mean;
  const double std_dev = std::sqrt(std::max(0.0, sum_sq / n - mean * mean));
  *std_dev_out = std_dev;
  if (std_dev < kMinStdDev) return false;
  // Conditioning of the geometric parameters with the contrast parameters projected out (Schur complement).
  const Eigen::Matrix3d schur =
      hessian.topLeftCorner<3, 3>() - hessian.topRightCorner<3, 2>() *
                                          hessian.bottomRightCorner<2, 2>().inverse() *
                                          hessian.bottomLeftCorner<2, 3>();
  // Compare in units where the scale column is a corner displacement (scale step * half window).
  const Eigen::Vector3d unit(1.0, 1.0, 1.0 / (half * stride));
  const Eigen::Matrix3d normalised = unit.asDiagonal() * schur * unit.asDiagonal();
  const double min_eigenvalue = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>()
                                    .computeDirect(normalised, Eigen::EigenvaluesOnly)
                                    .eigenvalues()(0);
  if (!(min_eigenvalue / n > kMinEigenvaluePerPixel)) return false;
  *inverse_hessian = hessian.inverse().cast<float>();
  // Without the scale parameter (coarse levels): invert the 4x4 system of (dx, dy, lambda, delta).
  Eigen::Matrix4d reduced;
  const int keep[4] = {0, 1, 3, 4};
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) reduced(i, j) = hessian(keep[i], keep[j]);
  }
  const Eigen::Matrix4d reduced_inverse = reduced.inverse();
  inverse_hessian_translation->setZero();
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j)
      (*inverse_hessian_translation)(keep[i], keep[j]) = static_cast<float>(reduced_inverse(i, j));
  }
  return true;
}

// One reference window as seen by the Gauss-Newton iterations.
struct WindowView {
  int size = 0;
  int stride = 1;  // spacing of the samples in reference pixels
  const float* t = nullptr;  // centred values, then Tx, Ty, u.grad T (size^2 floats each)
  double mean = 0.0;
  const Eigen::Matrix<float, 5, 5>* inverse_hessian = nullptr;
  const Eigen::Matrix<float, 5, 5>* inverse_hessian_translation = nullptr;  // scale fixed
};

// The warp being estimated, in pixels of the current level; contrast on the template side
// (I ~ lambda T + delta).
struct GaussNewtonState {
  double x = 0.0, y = 0.0, scale = 1.0, lambda = 1.0, delta = 0.0;
};

enum class LevelOutcome { kConverged, kMaxIterations, kOutOfImage, kBadStep, kScaleOutOfRange, kGiveUp };

// A window sampled at a state (IterateLevel's last samples, from which the affine warp can start without sampling
// the window again).
struct LastSample {
  GaussNewtonState state;
  float values[kMaxWindowSize * kMaxWindowSize];
};

struct LevelSettings {
  bool cubic = false;
  bool fine = false;  // level 0: out of image and give-up are final
  int max_iterations = 0;
  double epsilon = 0.01;
  // Scale prior (0 = none): weight mu of mu (log s - log s0)^2.
  double prior_weight = 0.0;
  double prior_scale = 1.0;
  // Stop with kGiveUp when, from iteration `give_up_iteration` on (0-based), the RMS residual (reference grey
  // levels) exceeds this.
  double give_up_rms = std::numeric_limits<double>::infinity();
  int give_up_iteration = 3;
  bool init_contrast = false;  // start the contrast from the first two moments of the first sampled window
  double min_gain = 0.25, max_gain = 4.0, min_scale = 0.5, max_scale = 2.0;
};

bool WindowFits(const cv::Mat& image, const GaussNewtonState& s, double half_extent, bool cubic) {
  const double extent = s.scale * half_extent;
  // Cubic sampling needs one more pixel on each side than bilinear sampling.
  const double margin = cubic ? 1.0 : 0.0;
  return s.x - extent >= margin && s.y - extent >= margin && s.x + extent < image.cols - 1 - margin &&
         s.y + extent < image.rows - 1 - margin;
}

void SampleWindow(const cv::Mat& image, const GaussNewtonState& s, const WindowView& window, bool cubic,
                  float* values) {
  const double spacing = s.scale * window.stride;
  if (cubic) {
    SampleWindowCubic(image, s.x, s.y, spacing, window.size, values);
  } else {
    SampleWindowBilinear(image, s.x, s.y, spacing, window.size, values);
  }
}

// Sum of x[0..n) and sum of (x - m)^2, in independent float partial sums (vectorisable; a serial double sum
// costs as much as a Gauss-Newton iteration).
constexpr int kLanes = 8;
double LaneSum(const float* x, int n) {
  float acc[kLanes] = {};
  int k = 0;
  for (; k + kLanes <= n; k += kLanes) {
    for (int l = 0; l < kLanes; ++l) acc[l] += x[k + l];
  }
  double sum = 0.0;
  for (; k < n; ++k) sum += x[k];
  for (int l = 0; l < kLanes; ++l) sum += acc[l];
  return sum;
}
double CenteredSquareSum(const float* x, int n, float m) {
  float acc[kLanes] = {};
  int k = 0;
  for (; k + kLanes <= n; k += kLanes) {
    for (int l = 0; l < kLanes; ++l) acc[l] += (x[k + l] - m) * (x[k + l] - m);
  }
  double sum = 0.0;
  for (; k < n; ++k) sum += static_cast<double>(x[k] - m) * (x[k] - m);
  for (int l = 0; l < kLanes; ++l) sum += acc[l];
  return sum;
}

// RMS of the errors e - d_lambda t - d_delta over the window (w x w, row-major) and the RMS of its worst 3x3
// block, divided by `lambda` (reference grey levels): the residual after a contrast step (d_lambda, d_delta)
// applied to the error image e = I - lambda t - delta of the last iteration.
void ErrorImageResiduals(const float* e, const float* t, int w, double d_lambda, double d_delta, double lambda,
                         double* rms, double* block_rms) {
  // Pixel (r, c) belongs to block (3 r / w, 3 c / w): columns [bound[j], bound[j + 1]) form block column j.
  int bound[4];
  for (int j = 0; j <= 3; ++j) bound[j] = (j * w + 2) / 3;
  double block_sse[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
  const float dl = static_cast<float>(d_lambda), dd = static_cast<float>(d_delta);
  for (int r = 0; r < w; ++r) {
    const int block_row = (r * 3 / w) * 3;
    const float* er = e + r * w;
    const float* tr = t + r * w;
    for (int j = 0; j < 3; ++j) {
      float sum = 0.0f;
      for (int c = bound[j]; c < bound[j + 1]; ++c) {
        const float v = er[c] - dl * tr[c] - dd;
        sum += v * v;
      }
      block_sse[block_row + j] += sum;
    }
  }
  double sse = 0.0, worst = 0.0;
  for (int b = 0; b < 9; ++b) {
    const int rows = bound[b / 3 + 1] - bound[b / 3], columns = bound[b % 3 + 1] - bound[b % 3];
    sse += block_sse[b];
    worst = std::max(worst, block_sse[b] / std::max(1, rows * columns));
  }
  *rms = std::sqrt(sse / (w * w)) / lambda;
  *block_rms = std::sqrt(worst) / lambda;
}

// Gauss-Newton iterations of (1) on one level (inverse compositional, see the header). On kConverged the
// state is the converged one (the window has not been re-sampled there). If `last_sample` is given, on kConverged
// it receives the state before the last step and the window sampled there. If `converged_rms` is given, on
// kConverged it receives the RMS residual of the window and `converged_block_rms` that of its worst 3x3 block
// (as Residuals() below), computed from the error image of the last iteration with the last contrast step
// applied: the geometry is then the one before the last step, which moved no window corner by more than
// `epsilon`, and no extra sampling of the window is needed.
LevelOutcome IterateLevel(const cv::Mat& image, const WindowView& window, bool estimate_scale,
                          const LevelSettings& settings, GaussNewtonState* state, int* iterations,
                          double* converged_rms = nullptr, double* converged_block_rms = nullptr,
                          LastSample* last_sample = nullptr) {
  const int w = window.size, n = w * w;
  const double half = 0.5 * (w - 1) * window.stride;  // half extent in reference pixels
  const float* t = window.t;
  const float* gx = t + n;
  const float* gy = t + 2 * n;
  const float* gs = t + 3 * n;
  const double mean = window.mean;
  const Eigen::Matrix<float, 5, 5>& inverse_hessian =
      estimate_scale ? *window.inverse_hessian : *window.inverse_hessian_translation;
  float values[kMaxWindowSize * kMaxWindowSize];
  bool init_contrast = settings.init_contrast;
  GaussNewtonState& s = *state;
  for (int iteration = 0; iteration < settings.max_iterations; ++iteration) {
    if (!WindowFits(image, s, half, settings.cubic)) return LevelOutcome::kOutOfImage;
    SampleWindow(image, s, window, settings.cubic, values);
    if (last_sample != nullptr) last_sample->state = s;  // where `values` were sampled
    if (init_contrast) {
      // Start the contrast from the first two moments of the window: lambda = std(I) / std(T),
      // delta = mean(I) - lambda mean(T); robust to large gain and bias changes and cheap.
      init_contrast = false;
      const double mean_i = LaneSum(values, n) / n;
      const double var_i = CenteredSquareSum(values, n, static_cast<float>(mean_i)) / n;
      const double var_t = CenteredSquareSum(t, n, 0.0f) / n;  // the template is centred
      if (var_i > 0.0 && var_t > 0.0) {
        s.lambda = std::clamp(std::sqrt(var_i / var_t), 1.0 / settings.max_gain, 1.0 / settings.min_gain);
        s.delta = mean_i - s.lambda * mean;
      }
    }
    // Error image and J0^T e (Segvic 2009 §4.2 warp; inverse compositional, see the header).
    const float lam = static_cast<float>(s.lambda), del = static_cast<float>(s.delta + s.lambda * mean);
    // Eight independent partial sums per quantity so that the compiler can keep them in SIMD registers
    // (float additions are not reassociated otherwise).
    float acc[6][kLanes] = {};
    int k = 0;
    for (; k + kLanes <= n; k += kLanes) {
      for (int l = 0; l < kLanes; ++l) {
        const float e = values[k + l] - lam * t[k + l] - del;
        values[k + l] = e;  // kept for the residual at convergence
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
      values[k] = e;
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
    ++*iterations;
    if (iteration >= settings.give_up_iteration &&
        sums[5] > n * settings.give_up_rms * settings.give_up_rms * s.lambda * s.lambda) {
      return LevelOutcome::kGiveUp;
    }
    Eigen::Matrix<float, 5, 1> b;
    b << sums[0], sums[1], sums[2], sums[3], sums[4];
    const Eigen::Matrix<float, 5, 1> h0_step = inverse_hessian * b;
    // Gauss-Newton step of (dx, dy, ds, dlambda, ddelta): D^-1 H0^-1 J0^T e with D = diag(l, l, l, 1, 1).
    const double lambda = s.lambda;
    Eigen::Matrix<double, 5, 1> step;
    step << h0_step(0) / lambda, h0_step(1) / lambda, h0_step(2) / lambda, h0_step(3), h0_step(4);
    if (estimate_scale && settings.prior_weight > 0.0) {
      // Prior mu (log s' - log s0)^2 with s' ~ s (1 - ds): adds mu to the ds diagonal and mu (log s - log
      // s0) to its right-hand side; solved with the precomputed inverse by Sherman-Morrison.
      Eigen::Matrix<double, 5, 1> u;
      for (int i = 0; i < 5; ++i) u(i) = inverse_hessian(i, 2);
      u.head<3>() /= lambda;
      u /= lambda;  // u = A^-1 e2 with A = D H0 D
      const double a22 = inverse_hessian(2, 2) / (lambda * lambda);
      const double c = std::log(s.scale / settings.prior_scale);
      const Eigen::Matrix<double, 5, 1> x0 = step + u * (settings.prior_weight * c);
      step = x0 - u * (settings.prior_weight * x0(2) / (1.0 + settings.prior_weight * a22));
    }
    const double step_x = step(0), step_y = step(1), step_s = step(2);
    if (!(1.0 + step_s > 0.5) || !std::isfinite(step_x) || !std::isfinite(step_y)) {
      return LevelOutcome::kBadStep;
    }
    // Inverse composition of the geometric step, additive contrast step.
    const double new_scale = s.scale / (1.0 + step_s);
    const double new_x = s.x - s.scale * step_x / (1.0 + step_s);
    const double new_y = s.y - s.scale * step_y / (1.0 + step_s);
    const double corner_shift =
        std::sqrt((new_x - s.x) * (new_x - s.x) + (new_y - s.y) * (new_y - s.y)) +
        std::abs(new_scale - s.scale) * half * 1.4142135623730951;
    s.x = new_x;
    s.y = new_y;
    s.scale = new_scale;
    if (!(s.scale > 0.5 * settings.min_scale && s.scale < 2.0 * settings.max_scale)) {
      return LevelOutcome::kScaleOutOfRange;
    }
    // Contrast step (on the offset of the centred template). Far from the solution (coarse levels, large
    // displacements) the contrast step can be wild; it is then skipped for this iteration, and the final
    // gain is checked against its range after convergence.
    const double new_lambda = s.lambda + step(3);
    const bool contrast_step = new_lambda > 1.0 / settings.max_gain && new_lambda < 1.0 / settings.min_gain;
    if (contrast_step) {
      s.delta += step(4) - step(3) * mean;
      s.lambda = new_lambda;
    }
    if (corner_shift < settings.epsilon) {
      if (last_sample != nullptr) {
        // The samples from the error image (computed with the contrast of the state they were sampled at).
        const GaussNewtonState& sampled_at = last_sample->state;
        const float lam_at = static_cast<float>(sampled_at.lambda);
        const float del_at = static_cast<float>(sampled_at.delta + sampled_at.lambda * mean);
        for (int q = 0; q < n; ++q) last_sample->values[q] = values[q] + lam_at * t[q] + del_at;
      }
      if (converged_rms != nullptr) {
        // The offset lambda * mean + delta of the centred template changes by step(4) in a contrast step.
        ErrorImageResiduals(values, t, w, contrast_step ? step(3) : 0.0, contrast_step ? step(4) : 0.0, s.lambda,
                            converged_rms, converged_block_rms);
      }
      return LevelOutcome::kConverged;
    }
  }
  return LevelOutcome::kMaxIterations;
}

// The affine fallback's warp x = A u + (x, y) at level 0, contrast on the template side as GaussNewtonState.
struct AffineState {
  Eigen::Matrix2d a = Eigen::Matrix2d::Identity();
  double x = 0.0, y = 0.0, lambda = 1.0, delta = 0.0;
};

#if defined(__SSE2__)
// CubicWeights of four fractions at once, with the same operations in the same order (the same floats).
inline void CubicWeights4(__m128 f, __m128* w0, __m128* w1, __m128* w2, __m128* w3) {
  const __m128 f2 = _mm_mul_ps(f, f), f3 = _mm_mul_ps(f2, f);
  const __m128 half = _mm_set1_ps(0.5f);
  *w0 = _mm_sub_ps(_mm_add_ps(_mm_mul_ps(_mm_set1_ps(-0.5f), f3), f2), _mm_mul_ps(half, f));
  *w1 = _mm_add_ps(_mm_sub_ps(_mm_mul_ps(_mm_set1_ps(1.5f), f3), _mm_mul_ps(_mm_set1_ps(2.5f), f2)), _mm_set1_ps(1.0f));
  *w2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_set1_ps(-1.5f), f3), _mm_mul_ps(_mm_set1_ps(2.0f), f2)),
                   _mm_mul_ps(half, f));
  *w3 = _mm_sub_ps(_mm_mul_ps(half, f3), _mm_mul_ps(half, f2));
}

// Splits four positions (x0, x1 in `lo`, x2, x3 in `hi`) into their integer parts, truncated as static_cast<int>, and
// their fractions as floats: the same values as the scalar static_cast<int>(x) and static_cast<float>(x - ix).
inline __m128 SplitPositions4(__m128d lo, __m128d hi, __m128i* integer) {
  const __m128i i_lo = _mm_cvttpd_epi32(lo), i_hi = _mm_cvttpd_epi32(hi);
  *integer = _mm_unpacklo_epi64(i_lo, i_hi);
  return _mm_movelh_ps(_mm_cvtpd_ps(_mm_sub_pd(lo, _mm_cvtepi32_pd(i_lo))),
                       _mm_cvtpd_ps(_mm_sub_pd(hi, _mm_cvtepi32_pd(i_hi))));
}
#endif

// Samples the w x w window of `s` (u integer offsets in [-half, half]^2) with cubic interpolation, one pixel at a
// time (the warp is not axis-aligned). False when a sample's 4x4 neighbourhood leaves the image.
bool SampleAffineWindow(const cv::Mat& image, const AffineState& s, int w, float* out) {
  const int half = w / 2;
  for (const int cu : {-half, half}) {
    for (const int cv_ : {-half, half}) {
      const double x = s.x + s.a(0, 0) * cu + s.a(0, 1) * cv_, y = s.y + s.a(1, 0) * cu + s.a(1, 1) * cv_;
      if (!(x >= 1.0 && y >= 1.0 && x < image.cols - 2.0 && y < image.rows - 2.0)) return false;
    }
  }
  const size_t stride = image.step1();
  const float* base = image.ptr<float>(0);
  for (int r = 0; r < w; ++r) {
    const double v = r - half;
    double x = s.x - s.a(0, 0) * half + s.a(0, 1) * v, y = s.y - s.a(1, 0) * half + s.a(1, 1) * v;
#if defined(__SSE2__)
    // Four samples at a time: their cubic weights in one go, the four taps of each of their four rows one unaligned
    // load (weighted by wy, summed vertically, weighted by wx), and a 4x4 transpose turning the four dot products into
    // one vertical sum. Lanes past the window's last column repeat its last sample and are not stored.
    for (int c0 = 0; c0 < w; c0 += 4) {
      const int lanes = std::min(4, w - c0);
      double xs[4], ys[4];
      for (int j = 0; j < 4; ++j) {
        if (j < lanes) {
          xs[j] = x;
          ys[j] = y;
          x += s.a(0, 0);
          y += s.a(1, 0);
        } else {
          xs[j] = xs[j - 1];
          ys[j] = ys[j - 1];
        }
      }
      alignas(16) int ix[4], iy[4];
      __m128i integer;
      const __m128 fx = SplitPositions4(_mm_loadu_pd(xs), _mm_loadu_pd(xs + 2), &integer);
      _mm_store_si128(reinterpret_cast<__m128i*>(ix), integer);
      const __m128 fy = SplitPositions4(_mm_loadu_pd(ys), _mm_loadu_pd(ys + 2), &integer);
      _mm_store_si128(reinterpret_cast<__m128i*>(iy), integer);
      __m128 wx0, wx1, wx2, wx3;
      CubicWeights4(fx, &wx0, &wx1, &wx2, &wx3);
      _MM_TRANSPOSE4_PS(wx0, wx1, wx2, wx3);  // now wxj: the four taps' weights of lane j
      __m128 wy0, wy1, wy2, wy3;
      CubicWeights4(fy, &wy0, &wy1, &wy2, &wy3);
      alignas(16) float wy[4][4];  // wy[k][j]: row k's weight of lane j
      _mm_store_ps(wy[0], wy0);
      _mm_store_ps(wy[1], wy1);
      _mm_store_ps(wy[2], wy2);
      _mm_store_ps(wy[3], wy3);
      const __m128 wx[4] = {wx0, wx1, wx2, wx3};
      __m128 products[4];
      for (int j = 0; j < 4; ++j) {
        const float* p = base + (iy[j] - 1) * stride + (ix[j] - 1);
        __m128 sum = _mm_mul_ps(_mm_loadu_ps(p), _mm_set1_ps(wy[0][j]));
        sum = _mm_add_ps(sum, _mm_mul_ps(_mm_loadu_ps(p + stride), _mm_set1_ps(wy[1][j])));
        sum = _mm_add_ps(sum, _mm_mul_ps(_mm_loadu_ps(p + 2 * stride), _mm_set1_ps(wy[2][j])));
        sum = _mm_add_ps(sum, _mm_mul_ps(_mm_loadu_ps(p + 3 * stride), _mm_set1_ps(wy[3][j])));
        products[j] = _mm_mul_ps(sum, wx[j]);
      }
      _MM_TRANSPOSE4_PS(products[0], products[1], products[2], products[3]);
      const __m128 samples = _mm_add_ps(_mm_add_ps(products[0], products[1]), _mm_add_ps(products[2], products[3]));
      float* o = out + r * w + c0;
      if (lanes == 4) {
        _mm_storeu_ps(o, samples);
      } else {
        alignas(16) float tail[4];
        _mm_store_ps(tail, samples);
        for (int j = 0; j < lanes; ++j) o[j] = tail[j];
      }
    }
#else
    for (int c = 0; c < w; ++c, x += s.a(0, 0), y += s.a(1, 0)) {
      const int fx = static_cast<int>(x), fy = static_cast<int>(y);
      float wx[4], wy[4];
      CubicWeights(static_cast<float>(x - fx), wx);
      CubicWeights(static_cast<float>(y - fy), wy);
      const float* p = base + (fy - 1) * stride + (fx - 1);
      float sum = 0.0f;
      for (int k = 0; k < 4; ++k, p += stride) {
        sum += wy[k] * (wx[0] * p[0] + wx[1] * p[1] + wx[2] * p[2] + wx[3] * p[3]);
      }
      out[r * w + c] = sum;
    }
#endif
  }
  return true;
}

// The affine warp of the fallback and the refinement (AlignmentOptions::affine_fallback, affine_refinement):
// Gauss-Newton on (A, d, lambda, delta) at level 0, inverse compositional with the contrast on the template side as
// IterateLevel. The Jacobian rows J0(u) = [Tx u, Tx v, Ty u, Ty v, Tx, Ty, T, 1] depend only on the reference, so
// H0^-1 (`inverse_hessian`, ReferencePatch::AffineInverseHessian) is computed once per reference; the step is
// D^-1 H0^-1 sum J0^T e with D = diag(lambda x 6, 1, 1). A geometric step (P, q) composes inversely:
// A <- A (I + P)^-1, d <- d - A (I + P)^-1 q. Stops with false when the window leaves the image, a step is
// singular, the residual stays above `give_up_rms` after 2 iterations or the iterations run out; on true `state`
// is the converged warp and `rms` / `block_rms` its residuals (from the last error image, as IterateLevel).
// `first_values`, when given, are the window already sampled at the starting state (LastSample::values): the first
// iteration uses them instead of sampling.
bool IterateAffine(const cv::Mat& image, const WindowView& window, const ReferencePatch::AffineMatrix& inverse_hessian,
                   int max_iterations, double epsilon, double give_up_rms, double min_gain, double max_gain,
                   AffineState* state, int* iterations, double* rms, double* block_rms,
                   const float* first_values = nullptr) {
  const int w = window.size, n = w * w, half = w / 2;
  const float* t = window.t;
  const float* gx = t + n;
  const float* gy = t + 2 * n;
  float values[kMaxWindowSize * kMaxWindowSize];
  AffineState& s = *state;
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    if (iteration == 0 && first_values != nullptr) {
      std::copy(first_values, first_values + n, values);
    } else if (!SampleAffineWindow(image, s, w, values)) {
      return false;
    }
    const float lam = static_cast<float>(s.lambda), del = static_cast<float>(s.delta + s.lambda * window.mean);
    // J0^T e row by row: within a row v is constant, so the v columns are v times the row's sums.
    Eigen::Matrix<double, 8, 1> b = Eigen::Matrix<double, 8, 1>::Zero();
    double sse = 0.0;
    for (int r = 0; r < w; ++r) {
      float sx = 0.f, sxu = 0.f, sy = 0.f, syu = 0.f, st = 0.f, se = 0.f, see = 0.f;
      int c = 0;
#if defined(__SSE2__)
      // Four pixels at a time, the rest of the row below.
      {
        const __m128 vlam = _mm_set1_ps(lam), vdel = _mm_set1_ps(del);
        __m128 vsx = _mm_setzero_ps(), vsxu = vsx, vsy = vsx, vsyu = vsx, vst = vsx, vse = vsx, vsee = vsx;
        for (; c + 4 <= w; c += 4) {
          const int k = r * w + c;
          const float u0 = static_cast<float>(c - half);
          const __m128 u = _mm_add_ps(_mm_set1_ps(u0), _mm_set_ps(3.f, 2.f, 1.f, 0.f));
          const __m128 tk = _mm_loadu_ps(t + k);
          const __m128 e = _mm_sub_ps(_mm_sub_ps(_mm_loadu_ps(values + k), _mm_mul_ps(vlam, tk)), vdel);
          _mm_storeu_ps(values + k, e);
          const __m128 gxe = _mm_mul_ps(_mm_loadu_ps(gx + k), e), gye = _mm_mul_ps(_mm_loadu_ps(gy + k), e);
          vsx = _mm_add_ps(vsx, gxe);
          vsxu = _mm_add_ps(vsxu, _mm_mul_ps(gxe, u));
          vsy = _mm_add_ps(vsy, gye);
          vsyu = _mm_add_ps(vsyu, _mm_mul_ps(gye, u));
          vst = _mm_add_ps(vst, _mm_mul_ps(tk, e));
          vse = _mm_add_ps(vse, e);
          vsee = _mm_add_ps(vsee, _mm_mul_ps(e, e));
        }
        const auto total = [](__m128 a) {
          alignas(16) float l[4];
          _mm_store_ps(l, a);
          return (l[0] + l[1]) + (l[2] + l[3]);
        };
        sx = total(vsx);
        sxu = total(vsxu);
        sy = total(vsy);
        syu = total(vsyu);
        st = total(vst);
        se = total(vse);
        see = total(vsee);
      }
#endif
      for (; c < w; ++c) {
        const int k = r * w + c;
        const float u = static_cast<float>(c - half);
        const float e = values[k] - lam * t[k] - del;
        values[k] = e;
        sx += gx[k] * e;
        sxu += gx[k] * e * u;
        sy += gy[k] * e;
        syu += gy[k] * e * u;
        st += t[k] * e;
        se += e;
        see += e * e;
      }
      const double v = r - half;
      b(0) += sxu;
      b(1) += v * sx;
      b(2) += syu;
      b(3) += v * sy;
      b(4) += sx;
      b(5) += sy;
      b(6) += st;
      b(7) += se;
      sse += see;
    }
    ++*iterations;
    if (iteration >= 2 && sse > n * give_up_rms * give_up_rms * s.lambda * s.lambda) return false;
    Eigen::Matrix<double, 8, 1> step = inverse_hessian * b;
    step.head<6>() /= s.lambda;
    if (!step.allFinite()) return false;
    Eigen::Matrix2d m;
    m << 1.0 + step(0), step(1), step(2), 1.0 + step(3);
    if (!(std::abs(m.determinant()) > 0.25)) return false;
    const Eigen::Matrix2d a = s.a * m.inverse();
    const Vector2d d = Vector2d(s.x, s.y) - a * step.segment<2>(4);
    double corner_shift = 0.0;
    for (const int cu : {-half, half}) {
      for (const int cv_ : {-half, half}) {
        const Vector2d u(cu, cv_);
        corner_shift = std::max(corner_shift, ((a - s.a) * u + d - Vector2d(s.x, s.y)).norm());
      }
    }
    s.a = a;
    s.x = d.x();
    s.y = d.y();
    const double new_lambda = s.lambda + step(6);
    const bool contrast_step = new_lambda > 1.0 / max_gain && new_lambda < 1.0 / min_gain;
    if (contrast_step) {
      s.delta += step(7) - step(6) * window.mean;
      s.lambda = new_lambda;
    }
    if (corner_shift < epsilon) {
      ErrorImageResiduals(values, t, w, contrast_step ? step(6) : 0.0, contrast_step ? step(7) : 0.0, s.lambda, rms,
                          block_rms);
      return true;
    }
  }
  return false;
}

// The smallest eigenvalue of the geometric block (dx, dy, ds) of a Gauss-Newton matrix of (1) with the contrast
// parameters projected out (Schur complement), the scale column as a corner displacement (ds times the half extent):
// how well the window determines position and scale in its weakest direction.
double SmallestGeometricEigenvalue(const Eigen::Matrix<double, 5, 5>& normal, double half) {
  const Eigen::Matrix2d contrast = normal.bottomRightCorner<2, 2>();
  if (!(std::abs(contrast.determinant()) > 0.0)) return 0.0;
  const Eigen::Matrix3d schur = normal.topLeftCorner<3, 3>() -
                                normal.topRightCorner<3, 2>() * contrast.inverse() * normal.bottomLeftCorner<2, 3>();
  const Eigen::Vector3d unit(1.0, 1.0, 1.0 / half);
  const Eigen::Matrix3d normalised = unit.asDiagonal() * schur * unit.asDiagonal();
  return Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>()
      .computeDirect(normalised, Eigen::EigenvaluesOnly)
      .eigenvalues()(0);
}

// The robust fallback's Gauss-Newton iterations of (1) on one level (the header's ROBUST FALLBACK): inverse
// compositional with iteratively re-weighted least squares, the template's Jacobian J0 with Tukey's biweight of each
// pixel's error at `threshold_ref` (reference grey levels), so the 5x5 normal equations are formed anew each iteration.
// Returns true when it converged; then `trimmed_rms` is the RMS (reference grey levels) of the `keep` smallest errors
// at the converged state and `information_share` the smallest eigenvalue of the geometric block of sum J0^T J0 with
// the contrast projected out over those pixels, divided by the same over the whole window. False when it left the
// image, the scale its range, the normal equations were singular, it gave up or did not converge.
bool IterateLevelRobust(const cv::Mat& image, const WindowView& window, const LevelSettings& settings,
                        double max_residual, double threshold_ref, int keep, GaussNewtonState* state, int* iterations,
                        double* trimmed_rms, double* information_share) {
  const int w = window.size, n = w * w;
  const double half = 0.5 * (w - 1) * window.stride;
  const float* t = window.t;
  const float* gx = t + n;
  const float* gy = t + 2 * n;
  const float* gs = t + 3 * n;
  const double mean = window.mean;
  float values[kMaxWindowSize * kMaxWindowSize];
  GaussNewtonState& s = *state;
  Eigen::Matrix<double, 5, 5> h;
  for (int iteration = 0; iteration < settings.max_iterations; ++iteration) {
    if (!WindowFits(image, s, half, settings.cubic)) return false;
    SampleWindow(image, s, window, settings.cubic, values);
    const float lam = static_cast<float>(s.lambda), del = static_cast<float>(s.delta + s.lambda * mean);
    const float inverse_c2 = static_cast<float>(1.0 / (threshold_ref * threshold_ref * s.lambda * s.lambda));
    const float within_r = static_cast<float>((max_residual * max_residual) / (threshold_ref * threshold_ref));
    // Weighted normal equations: the 15 distinct sums of w J J^T and the 5 of w e J, J = [Tx, Ty, u.grad T, T, 1].
    double xx = 0, xy = 0, xs = 0, xt = 0, x1 = 0, yy = 0, ys = 0, yt = 0, y1 = 0, ss = 0, st = 0, s1 = 0, tt = 0,
           t1 = 0, ww = 0, bx = 0, by = 0, bs = 0, bt = 0, b1 = 0;
    int near = 0;  // pixels whose error is within R
    for (int k = 0; k < n; ++k) {
      const float e = values[k] - lam * t[k] - del;
      const float u2 = e * e * inverse_c2;
      near += u2 < within_r;
      if (u2 >= 1.0f) continue;
      const float one_minus = 1.0f - u2;
      const double wk = one_minus * one_minus;
      const double jx = gx[k], jy = gy[k], js = gs[k], jt = t[k], we = wk * e;
      const double wx = wk * jx, wy = wk * jy, ws = wk * js, wt = wk * jt;
      xx += wx * jx, xy += wx * jy, xs += wx * js, xt += wx * jt, x1 += wx;
      yy += wy * jy, ys += wy * js, yt += wy * jt, y1 += wy;
      ss += ws * js, st += ws * jt, s1 += ws;
      tt += wt * jt, t1 += wt, ww += wk;
      bx += we * jx, by += we * jy, bs += we * js, bt += we * jt, b1 += we;
    }
    ++*iterations;
    // Give up when, after a few iterations, too few pixels match for the trimmed test to pass.
    if (iteration >= settings.give_up_iteration && near < keep / 2) return false;
    h << xx, xy, xs, xt, x1,  //
        xy, yy, ys, yt, y1,   //
        xs, ys, ss, st, s1,   //
        xt, yt, st, tt, t1,   //
        x1, y1, s1, t1, ww;
    Eigen::Matrix<double, 5, 1> b;
    b << bx, by, bs, bt, b1;
    const Eigen::LDLT<Eigen::Matrix<double, 5, 5>> ldlt(h);
    if (ldlt.info() != Eigen::Success) return false;
    const Eigen::Matrix<double, 5, 1> h0_step = ldlt.solve(b);
    const double lambda = s.lambda;
    const double step_x = h0_step(0) / lambda, step_y = h0_step(1) / lambda, step_s = h0_step(2) / lambda;
    if (!(1.0 + step_s > 0.5) || !std::isfinite(step_x) || !std::isfinite(step_y) || !h0_step.allFinite()) return false;
    const double new_scale = s.scale / (1.0 + step_s);
    const double new_x = s.x - s.scale * step_x / (1.0 + step_s);
    const double new_y = s.y - s.scale * step_y / (1.0 + step_s);
    const double corner_shift =
        std::hypot(new_x - s.x, new_y - s.y) + std::abs(new_scale - s.scale) * half * 1.4142135623730951;
    s.x = new_x;
    s.y = new_y;
    s.scale = new_scale;
    if (!(s.scale > settings.min_scale && s.scale < settings.max_scale)) return false;
    const double new_lambda = s.lambda + h0_step(3);
    if (new_lambda > 1.0 / settings.max_gain && new_lambda < 1.0 / settings.min_gain) {
      s.delta += h0_step(4) - h0_step(3) * mean;
      s.lambda = new_lambda;
    }
    if (corner_shift < settings.epsilon) {
      // The errors at the converged state, trimmed to the `keep` smallest; how well those pixels alone determine
      // position and scale against the whole window (the smallest eigenvalue of the geometric block of sum J0^T J0,
      // contrast projected out, over the kept pixels and over all).
      if (!WindowFits(image, s, half, settings.cubic)) return false;
      SampleWindow(image, s, window, settings.cubic, values);
      const float lam2 = static_cast<float>(s.lambda), del2 = static_cast<float>(s.delta + s.lambda * mean);
      int order[kMaxWindowSize * kMaxWindowSize];
      for (int k = 0; k < n; ++k) {
        const float e = values[k] - lam2 * t[k] - del2;
        values[k] = e * e;
        order[k] = k;
      }
      std::nth_element(order, order + (keep - 1), order + n, [&values](int a, int b) { return values[a] < values[b]; });
      double sum = 0.0;
      for (int k = 0; k < keep; ++k) sum += values[order[k]];
      *trimmed_rms = std::sqrt(sum / keep) / s.lambda;
      const auto weakest = [&](const int* pixels, int count) {
        Eigen::Matrix<double, 5, 5> normal = Eigen::Matrix<double, 5, 5>::Zero();
        for (int i = 0; i < count; ++i) {
          const int k = pixels[i];
          Eigen::Matrix<double, 5, 1> j;
          j << gx[k], gy[k], gs[k], t[k], 1.0;
          normal.selfadjointView<Eigen::Lower>().rankUpdate(j);
        }
        normal.triangularView<Eigen::Upper>() = normal.transpose();
        return SmallestGeometricEigenvalue(normal, half);
      };
      const double all = weakest(order, n);
      *information_share = all > 0.0 ? weakest(order, keep) / all : 0.0;
      return true;
    }
  }
  return false;
}

// RMS residual of (1) over the window sampled at `state`, and the RMS of the worst of its 3x3 blocks
// (reference grey levels).
void Residuals(const cv::Mat& image, const WindowView& window, bool cubic, const GaussNewtonState& state,
               double* rms, double* block_rms) {
  const int n = window.size * window.size;
  float values[kMaxWindowSize * kMaxWindowSize];
  SampleWindow(image, state, window, cubic, values);
  const float lam = static_cast<float>(state.lambda);
  const float del = static_cast<float>(state.delta + state.lambda * window.mean);
  for (int k = 0; k < n; ++k) values[k] -= lam * window.t[k] + del;
  ErrorImageResiduals(values, window.t, window.size, 0.0, 0.0, state.lambda, rms, block_rms);
}

}  // namespace

bool ReferencePatch::Create(const ImagePyramid& pyramid, const Vector2d& position, int window_size, int max_levels,
                            int scale_window_stride, PatchImage image) {
  num_levels_ = 0;
  scale_window_stride_ = 0;
  scale_source_ = cv::Mat();
  if (window_size < 3 || window_size > kMaxWindowSize || window_size % 2 == 0 || pyramid.Empty())
    return false;
  window_size_ = window_size;
  position_ = position;
  const int n = window_size * window_size;
  const int levels = std::max(0, std::min(max_levels, pyramid.NumLevels()));
  data_.assign(static_cast<size_t>(levels) * 4 * n, 0.0f);
  inverse_hessian_.resize(levels);
  inverse_hessian_translation_.resize(levels);
  mean_.assign(levels, 0.0);
  for (int level = 0; level < levels; ++level) {
    const double to_level = std::ldexp(1.0, -level);
    double std_dev = 0.0;
    const bool ok = CutWindow(pyramid.Level(level), position.x() * to_level, position.y() * to_level,
                              window_size, 1, level == 0, data_.data() + Offset(level), &mean_[level], &std_dev,
                              &inverse_hessian_[level], &inverse_hessian_translation_[level]);
    if (level == 0) std_dev_ = std_dev;
    if (!ok) break;
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
  // The wider level-0 window of the final refinement, when it fits: cut at its first use (ScaleWindowStride), from
  // level 0 as it is now. A prediction that does not align never reaches it, nor a track the affine refinement
  // settles (cut at first use, the simulator's repeat benchmark runs on 2.6 % fewer instructions).
  scale_data_.clear();
  const cv::Mat& level0 = pyramid.Level(0);
  if (scale_window_stride > 1 && scale_window_stride <= kMaxScaleWindowStride && level0.type() == CV_32FC1 &&
      WindowFitsImage(level0.size(), position.x(), position.y(), window_size, scale_window_stride, true)) {
    scale_image_size_ = level0.size();
    if (image == PatchImage::kKept) {
      scale_source_origin_ = cv::Point(0, 0);
      scale_source_ = level0;  // a handle: the pyramid's level 0 is not written again
    } else {
      // The pixels SampleWindowCubic reads (the window's extent, its 4x4 cubic taps), with a pixel to spare.
      const int ext_half = SampledSide(window_size, scale_window_stride) / 2;
      const int x0 = std::max(0, static_cast<int>(position.x() - ext_half) - 2);
      const int y0 = std::max(0, static_cast<int>(position.y() - ext_half) - 2);
      const int x1 = std::min(level0.cols, static_cast<int>(position.x() + ext_half) + 4);
      const int y1 = std::min(level0.rows, static_cast<int>(position.y() + ext_half) + 4);
      scale_source_origin_ = cv::Point(x0, y0);
      scale_source_ = level0(cv::Rect(x0, y0, x1 - x0, y1 - y0)).clone();
    }
    scale_window_stride_ = scale_window_stride;  // until CutScaleWindow finds otherwise
  }
  return true;
}

void ReferencePatch::CutScaleWindow() const {
  scale_data_.resize(static_cast<size_t>(4) * window_size_ * window_size_);
  const WindowPart where{scale_source_origin_, scale_image_size_};
  double std_dev = 0.0;
  if (!CutWindow(scale_source_, position_.x(), position_.y(), window_size_, scale_window_stride_, true,
                 scale_data_.data(), &scale_mean_, &std_dev, &scale_inverse_hessian_,
                 &scale_inverse_hessian_translation_, &where)) {
    scale_window_stride_ = 0;
    scale_data_.clear();
  }
  scale_source_ = cv::Mat();
}

const ReferencePatch::AffineMatrix* ReferencePatch::AffineInverseHessian() const {
  if (affine_state_ == 0) {
    affine_state_ = -1;
    if (num_levels_ == 0) return nullptr;
    // H0 = sum J0^T J0 over the level-0 window, J0(u) = [Tx u, Tx v, Ty u, Ty v, Tx, Ty, T, 1] (IterateAffine): the
    // rows J0(u) stacked in one n x 8 matrix and multiplied by Eigen's vectorised product (a per-pixel loop over the
    // upper triangle cost twice as many instructions at 320 px, most of them scalar).
    const int w = window_size_, n = w * w, half = w / 2;
    const float* t = Centered(0);
    const float* gx = Gx(0);
    const float* gy = Gy(0);
    thread_local Eigen::Matrix<float, Eigen::Dynamic, 8> j;
    j.resize(n, 8);
    for (int k = 0; k < n; ++k) {
      const float u = static_cast<float>(k % w - half), v = static_cast<float>(k / w - half);
      j(k, 0) = gx[k] * u;
      j(k, 1) = gx[k] * v;
      j(k, 2) = gy[k] * u;
      j(k, 3) = gy[k] * v;
      j(k, 4) = gx[k];
      j(k, 5) = gy[k];
      j(k, 6) = t[k];
      j(k, 7) = 1.0f;
    }
    Eigen::Matrix<float, 8, 8> h = Eigen::Matrix<float, 8, 8>::Zero();
    h.selfadjointView<Eigen::Upper>().rankUpdate(j.transpose());
    const Eigen::Matrix<double, 8, 8> h0 = h.selfadjointView<Eigen::Upper>().toDenseMatrix().cast<double>();
    const Eigen::LDLT<Eigen::Matrix<double, 8, 8>> solver(h0);
    if (solver.info() != Eigen::Success || !(solver.vectorD().minCoeff() > 1e-9 * solver.vectorD().maxCoeff())) {
      return nullptr;
    }
    affine_inverse_hessian_ = solver.solve(Eigen::Matrix<double, 8, 8>::Identity());
    affine_state_ = 1;
  }
  return affine_state_ == 1 ? &affine_inverse_hessian_ : nullptr;
}

namespace {

// AlignToReference starting at pyramid level `start_level` at most.
AlignmentResult AlignFromLevel(const ImagePyramid& pyramid, const ReferencePatch& reference,
                               const WarpState& initial, const AlignmentOptions& options, int start_level) {
  AlignmentResult result;
  result.warp = initial;
  result.residual = std::numeric_limits<double>::infinity();
  if (!reference.Valid() || pyramid.Empty() || !(initial.gain > 0.0) || !(initial.scale > 0.0)) return result;
  const int w = reference.WindowSize();
  const int coarsest = std::max(0, std::min({pyramid.NumLevels() - 1, reference.NumLevels() - 1, start_level}));

  GaussNewtonState state;
  // Template-side contrast: I ~ lambda T + delta, i.e. alpha = 1 / lambda, beta = -delta / lambda.
  state.lambda = 1.0 / initial.gain;
  state.delta = -initial.bias / initial.gain;
  state.scale = initial.scale;
  Vector2d position = initial.position;

  LevelSettings settings;
  settings.min_gain = options.min_gain;
  settings.max_gain = options.max_gain;
  settings.min_scale = options.min_scale;
  settings.max_scale = options.max_scale;
  settings.prior_scale = initial.scale;
  // Weight of the scale prior in units of squared grey levels (residual noise of 1 grey level per pixel).
  settings.prior_weight =
      options.scale_prior_sigma > 0.0 ? 1.0 / (options.scale_prior_sigma * options.scale_prior_sigma) : 0.0;
  settings.init_contrast = options.contrast_from_moments;

  const auto finish = [&](TrackStatus status, const GaussNewtonState& s, double to_level) {
    result.status = status;
    result.warp.position = Vector2d(s.x, s.y) / to_level;
    result.warp.scale = s.scale;
    result.warp.gain = 1.0 / s.lambda;
    result.warp.bias = -s.delta / s.lambda;
    return result;
  };

  for (int level = coarsest; level >= 0; --level) {
    const cv::Mat& image = pyramid.Level(level);
    const double to_level = std::ldexp(1.0, -level);
    state.x = position.x() * to_level;
    state.y = position.y() * to_level;
    const bool fine = level == 0;
    // Coarse levels estimate translation and contrast only (the scale is kept): with the scale free, coarse
    // windows far from the solution too easily shrink or grow onto a neighbouring structure.
    const bool estimate_scale = fine || !options.coarse_translation_only;
    WindowView window;
    window.size = w;
    window.t = reference.Centered(level);
    window.mean = reference.Mean(level);
    window.inverse_hessian = &reference.InverseHessian(level);
    window.inverse_hessian_translation = &reference.InverseHessianTranslation(level);
    settings.cubic = fine && options.cubic_interpolation;
    settings.fine = fine;
    settings.max_iterations = fine ? options.max_iterations_fine : options.max_iterations_coarse;
    settings.epsilon = fine ? options.convergence_epsilon : options.convergence_epsilon_coarse;
    // At level 0, a window whose residual stays far above R after a few iterations will not match
    // (occlusion, wrong basin): stop early instead of spending the remaining iterations.
    settings.give_up_rms = fine ? kGiveUpResidualFactor * options.max_residual
                                : std::numeric_limits<double>::infinity();
    // At level 0 with an affine warp on, the last samples start it (they are the window at the state before the
    // converged step, which moved no corner by more than epsilon: one sampling fewer); the affine warp samples
    // cubically, so only cubic samples are kept.
    const GaussNewtonState level_start = state;
    LastSample last_sample;
    const bool keep_sample = fine && settings.cubic && (options.affine_refinement || options.affine_fallback);
    const LevelOutcome outcome = IterateLevel(image, window, estimate_scale, settings, &state, &result.iterations,
                                              &result.residual, &result.block_residual,
                                              keep_sample ? &last_sample : nullptr);
    bool last_sample_current = keep_sample;  // false once `state` is no longer IterateLevel's
    settings.init_contrast = false;
    if (!fine) {
      // kOutOfImage: the window does not fit on this coarse level; continue on the finer one.
      if (outcome == LevelOutcome::kBadStep) {
        return finish(TrackStatus::kNotConverged, state, to_level);
      } else if (outcome == LevelOutcome::kScaleOutOfRange) {
        return finish(TrackStatus::kScaleOutOfRange, state, to_level);
      }
      position = Vector2d(state.x, state.y) / to_level;
      continue;
    }
    // The affine warp from `from` (AlignmentOptions::affine_fallback and affine_refinement): true when adopted, with
    // `result` filled in as tracked. `from` is IterateLevel's converged state while `last_sample_current`: the warp
    // then starts where that was last sampled, from those samples.
    const auto align_affine = [&](const GaussNewtonState& from) {
      const GaussNewtonState& start = last_sample_current ? last_sample.state : from;
      AffineState affine;
      affine.a = Eigen::Matrix2d::Identity() * start.scale;
      affine.x = start.x;
      affine.y = start.y;
      affine.lambda = start.lambda;
      affine.delta = start.delta;
      double rms = 0.0, block_rms = 0.0;
      const ReferencePatch::AffineMatrix* inverse_hessian = reference.AffineInverseHessian();
      if (inverse_hessian == nullptr ||
          !IterateAffine(image, window, *inverse_hessian, options.max_iterations_affine,
                         options.convergence_epsilon_affine, kAffineResidualFactor * options.max_residual,
                         options.min_gain, options.max_gain, &affine, &result.iterations, &rms, &block_rms,
                         last_sample_current ? last_sample.values : nullptr)) {
        return false;
      }
      const Eigen::JacobiSVD<Eigen::Matrix2d> svd(affine.a);
      const double largest = svd.singularValues()(0), smallest = svd.singularValues()(1);
      const double gain = 1.0 / affine.lambda;
      if (!(affine.a.determinant() > 0.0) || !(smallest >= options.min_scale && largest <= options.max_scale) ||
          !(largest <= options.max_affine_anisotropy * smallest) ||
          !(gain >= options.min_gain && gain <= options.max_gain) || !(rms <= options.max_residual) ||
          !(block_rms <= options.max_block_residual) ||
          std::hypot(affine.x - from.x, affine.y - from.y) > options.max_affine_shift) {
        return false;
      }
      GaussNewtonState adopted = from;
      adopted.x = affine.x;
      adopted.y = affine.y;
      adopted.scale = std::sqrt(affine.a.determinant());
      adopted.lambda = affine.lambda;
      adopted.delta = affine.delta;
      result.residual = rms;
      result.block_residual = block_rms;
      result.converged = true;
      result.affine_used = true;
      finish(TrackStatus::kTracked, adopted, 1.0);
      return true;
    };
    // The robust fallback (AlignmentOptions::robust_fallback, the header's ROBUST FALLBACK) from where level 0 started,
    // on the 15x15 window (not the wider one, whose outer ring more often reaches another surface): true when
    // adopted, with `result` filled in as tracked; else `result` is as it was but for its iteration count.
    const auto align_robust = [&]() {
      if (!options.robust_fallback) return false;
      GaussNewtonState robust = level_start;
      const int keep = std::max(1, static_cast<int>(std::ceil(options.robust_min_inlier_fraction * w * w)));
      double trimmed = 0.0, information_share = 0.0;
      if (!IterateLevelRobust(image, window, settings, options.max_residual,
                              options.robust_threshold_factor * options.max_residual, keep, &robust, &result.iterations,
                              &trimmed, &information_share)) {
        return false;
      }
      const double gain = 1.0 / robust.lambda;
      if (!(trimmed <= options.max_residual) || !(information_share >= options.robust_min_information_share) ||
          !(gain >= options.min_gain) || !(gain <= options.max_gain) || robust.scale < options.min_scale ||
          robust.scale > options.max_scale) {
        return false;
      }
      result.residual = trimmed;
      result.block_residual = 0.0;
      result.converged = true;
      result.robust_used = true;
      finish(TrackStatus::kTracked, robust, 1.0);
      return true;
    };
    switch (outcome) {
      case LevelOutcome::kConverged:
        break;
      case LevelOutcome::kOutOfImage:
        return finish(TrackStatus::kOutOfImage, state, 1.0);
      case LevelOutcome::kScaleOutOfRange:
        return finish(TrackStatus::kScaleOutOfRange, state, 1.0);
      case LevelOutcome::kGiveUp: {
        // Report the residual of the state where the alignment gave up.
        if (WindowFits(image, state, w / 2, settings.cubic)) {
          Residuals(image, window, settings.cubic, state, &result.residual, &result.block_residual);
        }
        if (align_robust()) return result;
        return finish(TrackStatus::kResidualTooLarge, state, 1.0);
      }
      case LevelOutcome::kBadStep:
      case LevelOutcome::kMaxIterations:
        if (align_robust()) return result;
        if (WindowFits(image, state, w / 2, settings.cubic)) {
          Residuals(image, window, settings.cubic, state, &result.residual, &result.block_residual);
        }
        return finish(TrackStatus::kNotConverged, state, 1.0);
    }
    result.converged = true;
    if (!WindowFits(image, state, w / 2, settings.cubic)) return finish(TrackStatus::kOutOfImage, state, 1.0);
    // The affine refinement starts only from an alignment the checks below accept (residuals, scale, gain), before
    // the wider window's: adopted, it settles position and shape on the 15x15 window itself, and the wider window
    // would only have moved its start (what the paper's warp reaches without it stands as before).
    if (options.affine_refinement && result.residual <= options.max_residual &&
        result.block_residual <= options.max_block_residual && state.scale >= options.min_scale &&
        state.scale <= options.max_scale && 1.0 / state.lambda >= options.min_gain &&
        1.0 / state.lambda <= options.max_gain) {
      const AlignmentResult isotropic = result;
      if (align_affine(state)) return result;
      result = isotropic;
    }
    // Final refinement of scale, position and contrast on the larger level-0 window (see the header), for
    // windows that match. It is adopted only when it converges and the larger window is consistent with the
    // model (its RMS within R, its worst 3x3 block within the block limit: an occluder or a depth
    // discontinuity in the outer ring rejects it) and it moves the position by less than
    // `max_scale_window_shift`; otherwise the 15x15 result stands.
    // (ScaleWindowStride last: it cuts the window at its first call.)
    if (options.scale_window_stride > 1 && result.residual <= options.max_residual &&
        result.block_residual <= options.max_block_residual && reference.ScaleWindowStride() > 1) {
      WindowView wide;
      wide.size = w;
      wide.stride = reference.ScaleWindowStride();
      wide.t = reference.ScaleWindow();
      wide.mean = reference.ScaleWindowMean();
      wide.inverse_hessian = &reference.ScaleWindowInverseHessian();
      wide.inverse_hessian_translation = &reference.ScaleWindowInverseHessianTranslation();
      const double wide_half = 0.5 * (w - 1) * wide.stride;
      GaussNewtonState refined = state;
      LevelSettings refine = settings;
      refine.max_iterations = options.max_iterations_scale_window;
      // Started from the converged 15x15 solution, a wide window that will match has its RMS below R
      // after two steps; one still above 1.5 R then is not adopted anyway (KITTI 07 at 320x240: none of the
      // adopted refinements, and a third of the others, which then need no further iterations).
      refine.give_up_rms = kWideGiveUpResidualFactor * options.max_residual;
      refine.give_up_iteration = 2;
      int iterations = 0;
      double wide_rms = 0.0, wide_block = 0.0;
      if (WindowFits(image, refined, wide_half, settings.cubic) &&
          IterateLevel(image, wide, true, refine, &refined, &iterations, &wide_rms, &wide_block) ==
              LevelOutcome::kConverged &&
          std::hypot(refined.x - state.x, refined.y - state.y) <= options.max_scale_window_shift &&
          WindowFits(image, refined, wide_half, settings.cubic)) {
        double core_rms = 0.0, core_block = 0.0;
        Residuals(image, window, settings.cubic, refined, &core_rms, &core_block);
        if (wide_rms <= options.max_residual && wide_block <= options.max_residual) {
          state = refined;
          last_sample_current = false;
          result.residual = core_rms;
          result.block_residual = core_block;
          result.scale_window_used = true;
        }
      }
      result.iterations += iterations;
    }
    finish(TrackStatus::kTracked, state, 1.0);
    if (state.scale < options.min_scale || state.scale > options.max_scale) {
      result.status = TrackStatus::kScaleOutOfRange;
    } else if (result.warp.gain < options.min_gain || result.warp.gain > options.max_gain) {
      result.status = TrackStatus::kGainOutOfRange;
    } else if (!(result.residual <= options.max_residual) ||
               !(result.block_residual <= options.max_block_residual)) {
      // Above R: the affine fallback when it is on and the residual within 1.5 R.
      const AlignmentResult isotropic = result;
      if (!options.affine_fallback || !(result.residual <= kAffineResidualFactor * options.max_residual) ||
          !align_affine(state)) {
        result = isotropic;
        if (!align_robust()) result.status = TrackStatus::kResidualTooLarge;
      }
    }
    return result;
  }
  return result;  // not reached: level 0 always returns
}

}  // namespace

AlignmentResult AlignToReference(const ImagePyramid& pyramid, const ReferencePatch& reference,
                                 const WarpState& initial, const AlignmentOptions& options) {
  return AlignFromLevel(pyramid, reference, initial, options, std::numeric_limits<int>::max());
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
  auto reference = std::make_shared<ReferencePatch>();
  if (!reference->Create(pyramid, position, options_.alignment.window_size, options_.num_levels,
                         options_.alignment.scale_window_stride)) {
    return kInvalidFeatureId;
  }
  AlignmentResult alignment;
  alignment.warp.position = position;
  alignment.residual = 0.0;
  alignment.converged = true;
  alignment.status = TrackStatus::kTracked;
  const feature_t added = AddFeature(std::shared_ptr<const ReferencePatch>(std::move(reference)), alignment, id);
  if (added != kInvalidFeatureId) placed_.back() = 0;  // the reference is this image's own
  return added;
}

std::vector<feature_t> FeatureTracker::AddFeatures(const ImagePyramid& pyramid,
                                                   const std::vector<Vector2d>& positions) {
  std::vector<feature_t> ids;
  ids.reserve(positions.size());
  for (const Vector2d& p : positions) ids.push_back(AddFeature(pyramid, p));
  return ids;
}

feature_t FeatureTracker::AddFeature(const ReferencePatch& reference, const AlignmentResult& alignment, feature_t id) {
  return AddFeature(std::make_shared<const ReferencePatch>(reference), alignment, id);
}

feature_t FeatureTracker::AddFeature(std::shared_ptr<const ReferencePatch> reference, const AlignmentResult& alignment,
                                     feature_t id) {
  if (reference == nullptr || !reference->Valid() || reference->WindowSize() != options_.alignment.window_size)
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
  feature.robust_acquired = alignment.robust_used;
  features_.push_back(feature);
  references_.push_back(std::move(reference));
  velocities_.push_back(Vector2d::Zero());
  placed_.push_back(1);
  return id;
}

const std::vector<TrackedFeature>& FeatureTracker::Track(const ImagePyramid& pyramid) {
  last_results_.clear();
  std::vector<AlignmentResult>& results = scratch_results_;
  results.assign(features_.size(), AlignmentResult());
  // The features a robust alignment added keep the robust fallback (FeatureTrackerOptions::robust_acquired_tracking).
  AlignmentOptions robust_alignment = options_.alignment;
  robust_alignment.robust_fallback = true;
  const auto align = [&](size_t i, const Vector2d& velocity, bool own_velocity) {
    const TrackedFeature& feature = features_[i];
    const bool robust = options_.robust_acquired_tracking && feature.robust_acquired;
    const AlignmentOptions& alignment = robust ? robust_alignment : options_.alignment;
    WarpState initial = feature.warp;
    const bool predicted = velocity.squaredNorm() > 0.25;
    if (predicted) initial.position += velocity;
    // A feature tracked in the previous frame with its own velocity has a good guess: start at a fine level
    // and fall back to the full coarse-to-fine alignment unless that converged (onto a window that does not
    // match, residual above R; see FeatureTrackerOptions::predicted_start_level).
    bool done = false;
    if (options_.predicted_start_level >= 0 &&
        ((own_velocity && feature.num_frames >= 2) || (options_.placed_features_start_fine && placed_[i]))) {
      results[i] = AlignFromLevel(pyramid, *references_[i], initial, alignment, options_.predicted_start_level);
      done = results[i].ok() || (results[i].converged && results[i].status == TrackStatus::kResidualTooLarge);
    }
    if (!done) results[i] = AlignToReference(pyramid, *references_[i], initial, alignment);
    // The guess may be wrong after an abrupt change of motion: retry from the last position, unless the
    // alignment converged onto a window that does not match (residual above R): on KITTI 07 at 320x240 those
    // retries succeeded for 0.3 % of the features and cost a quarter of the tracking time.
    if (!results[i].ok() && predicted && results[i].status != TrackStatus::kResidualTooLarge) {
      AlignmentResult retry = AlignToReference(pyramid, *references_[i], feature.warp, alignment);
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
    align(i, velocities_[i], true);
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
  for (size_t i : without_velocity) align(i, common_motion, false);

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
      placed_[kept] = placed_[i];
      if (kept != i) references_[kept] = std::move(references_[i]);
      ++kept;
    }
    last_results_.push_back(updated);
  }
  features_.resize(kept);
  references_.resize(kept);
  velocities_.resize(kept);
  placed_.resize(kept);
  return last_results_;
}

bool FeatureTracker::Remove(feature_t id) {
  const int index = IndexOf(id);
  if (index < 0) return false;
  features_.erase(features_.begin() + index);
  references_.erase(references_.begin() + index);
  velocities_.erase(velocities_.begin() + index);
  placed_.erase(placed_.begin() + index);
  return true;
}

bool FeatureTracker::SetReference(feature_t id, const ImagePyramid& pyramid, const Vector2d& position) {
  const int index = IndexOf(id);
  if (index < 0) return false;
  auto reference = std::make_shared<ReferencePatch>();
  if (!reference->Create(pyramid, position, options_.alignment.window_size, options_.num_levels,
                         options_.alignment.scale_window_stride))
    return false;
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
  return index < 0 ? nullptr : references_[index].get();
}

int FeatureTracker::IndexOf(feature_t id) const {
  for (size_t i = 0; i < features_.size(); ++i) {
    if (features_[i].id == id) return static_cast<int>(i);
  }
  return -1;
}

}  // namespace retrace
