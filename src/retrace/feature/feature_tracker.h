#pragma once

// Reference-aligned differential point-feature tracker (Segvic 2009, §4.2; design.md §4.1).
//
// Integrating frame-to-frame motion drifts, so every feature keeps its REFERENCE appearance T (a window of
// `window_size` x `window_size` pixels, 15x15 by default, cut from the image where the feature was
// (re)defined) and is aligned to it in each new image I with a warp of translation d, isotropic scale s and
// affine contrast (gain alpha, bias beta):
//
//     minimise over (d, s, alpha, beta)   sum_u [ alpha * I(s * u + d) + beta - T(u) ]^2,          (1)
//
// u running over the integer offsets of the window around the reference position (Segvic 2009, §4.2:
// "translation, isotropic scaling, and affine contrast compensation"). The minimisation is Gauss-Newton,
// coarse to fine on the pre-smoothed ImagePyramid (the reference window is cut at every level, so a 15x15
// window at level 2 of a 3-level pyramid spans 60x60 input pixels and displacements well over 10 px
// converge).
//
// Implementation: inverse compositional with the contrast moved to the template side (Baker & Matthews,
// "Lucas- Kanade 20 years on", simultaneous inverse compositional with linear appearance): we fit I(s u + d)
// ~ lambda * T(W(u; dp)) + delta with lambda = 1/alpha, delta = -beta/alpha. The Jacobian rows J0(u) = [Tx,
// Ty, u.grad T, T, 1] depend only on the reference, so the 5x5 Gauss-Newton matrix H0 = sum J0^T J0 and its
// inverse are computed once per reference and level; with J = J0 diag(lambda, lambda, lambda, 1, 1) the step
// is diag(1/lambda, 1/lambda, 1/lambda, 1, 1) H0^-1 sum J0^T e (the template is stored zero-mean so that the
// two contrast columns are orthogonal). An iteration therefore costs one interpolated sample and six
// multiply-adds per window pixel, and no allocation. Geometric steps are composed inversely: (s, d) <- (s /
// (1 + ds), d - s dd / (1 + ds)); contrast steps are additive.
//
// Choices that matter for accuracy and robustness (each an option, measured in feature_tracker_test.cc):
//  - the contrast starts from the first two moments of the window (robust to gain 0.6..1.5 and bias +-30);
//  - coarse levels estimate translation and contrast only, the scale is estimated at level 0;
//  - level 0 samples the image with cubic (Keys) interpolation: bilinear sampling blurs by an amount that
//  depends
//    on the sub-pixel phase, which biases scale and position by several hundredths of a pixel;
//  - the FeatureTracker uses a weak prior on the scale change per frame (std 2 %), so windows whose scale is
//  badly
//    determined do not trade scale against position;
//  - alignment gives up early when the residual at level 0 stays far above R;
//  - a final refinement on a WIDER level-0 window (below).
//
// WIDER WINDOW. The scale of a 15x15 window around a corner is weakly observable: an ideal corner is
// self-similar under scaling about its apex, so the scale rests on the little other structure in the window
// and on the edge blur, and small model errors (interpolation, aliasing, quantisation, the fixed
// pre-smoothing) bias it by 1-8 % (measured on synthetic warps, feature_tracker_test.cc). So once the 15x15
// alignment has converged with a residual within R, scale, position and contrast are refined on a second
// reference window of the same 15x15 samples spaced `scale_window_stride` pixels apart (3: spanning 43 px;
// same cost per iteration as the 15x15 window). The refinement is adopted only when it converges, moves the
// position by at most `max_scale_window_shift` and the wide window matches (its RMS and the RMS of its worst
// 3x3 block within R: an occluder or a depth edge in the outer ring rejects it); otherwise the 15x15 result
// stands (AlignmentResult::scale_window_used says which). The refinement gives up when the wide window's
// RMS is still above 1.5 R after two iterations (it would not be adopted). The reported residual is always
// that of the central 15x15 window. Measured on synthetic warps (translation up to 15 px, scale 0.8-1.25, gain 0.6-1.5,
// bias +-30): max position error 0.09 px and max scale error 0.4 % on the case corners, against 0.2 px and
// 8 % with the 15x15 window alone.

// AFFINE FALLBACK (off by default; `repeat --affine` turns it on). A reference cut in a key-image and aligned in an
// image taken beside the taught path (a lateral offset) sees a facade more or less obliquely: foreshortened across,
// sheared along the vertical, which (1) cannot absorb, so the alignment converges with its residual above R. When it
// does so within 1.5 R at level 0, the geometric part is re-estimated as a full affine map x = A u + d from where it
// ended — the affine Lucas-Kanade of Baker & Matthews (same paper, inverse compositional, the 8x8 Gauss-Newton matrix
// of [Tx u, Tx v, Ty u, Ty v, Tx, Ty, T, 1] inverted once per reference, per-pixel cubic sampling since the warp is no
// longer axis-aligned) — and adopted when it converges within `max_affine_shift` of where it started with its residuals
// within the limits, the singular values of A in [min_scale, max_scale] and their ratio at most
// `max_affine_anisotropy`; the scale reported is sqrt(det A). Measured in feature_tracker_test.cc on a texture
// compressed to 0.7 across and sheared by 0.25: of 40 predicted features (1.1 px off) the paper's warp accepts 14, the
// fallback 12 more, at a median error of 0.02 px. The features the paper's warp accepts there are off by 0.36 px
// (median): a window sheared that much still matches an isotropic warp within R at a shifted centre, which the fallback
// does not revisit.
//
// AFFINE REFINEMENT (off by default here; on in the localizer, LocalizerOptions::affine_refinement). The fallback
// revisits only rejected windows; a window sheared or foreshortened a little still matches the isotropic warp within R,
// at a centre pulled towards where the distortion is balanced (above: 0.36 px median under a shear of 0.25). With
// `affine_refinement` every alignment accepted at level 0 is refined by the same affine Gauss-Newton from the accepted
// warp and the refined one adopted when it passes the fallback's checks — the affine model of a small planar patch's
// appearance, which Shi & Tomasi ("Good features to track", CVPR 1994) use to check a feature against its first
// view. The inverse 8x8 Gauss-Newton matrix is computed once per reference (ReferencePatch::AffineInverseHessian), and
// the affine warp (of the fallback too) starts where the paper's warp last sampled the window, from those samples (one
// sampling fewer).
// Measured in feature_tracker_test.cc (AffineRefinementRemovesTheShearBias).
//
// ROBUST FALLBACK (off by default; on for the mapped features a relocalization after a loss locates,
// LocalizerOptions::relocalization_robust_alignment). Under another sun a window often straddles two surfaces whose
// brightness changed differently — a facade and the sky, a wall and its windows, a cast shadow's edge — and no single
// gain and bias brings all of it within R. When the alignment at level 0 ends with its residual above R (converged or
// given up) or does not converge, it is run again at level 0 from where that level started, with every pixel weighted
// by Tukey's biweight of its error, w = (1 - (e / c)^2)^2 for |e| < c = `robust_threshold_factor` R, 0 beyond
// (iteratively re-weighted Gauss-Newton on the same template Jacobian J0: the 5x5 normal equations sum w J0^T J0 are
// formed anew each iteration; Hager & Belhumeur, "Efficient region tracking with parametric models of geometry and
// illumination", PAMI 1998, robust estimation for illumination and partial occlusion; Baker, Gross, Matthews,
// "Lucas-Kanade 20 years on, part 2", 2003, robust error functions with the inverse compositional algorithm). It is
// adopted when the `robust_min_inlier_fraction` of the window's pixels with the smallest errors have an RMS within R
// (a trimmed residual, as least trimmed squares, Rousseeuw 1984) and those pixels alone still determine position and
// scale: the smallest eigenvalue of their Gauss-Newton matrix's geometric block (contrast projected out) is at least
// `robust_min_information_share` of the whole window's.
// It gives up when, from its fourth iteration on, fewer than half as many pixels as that fraction asks lie within R
// (the window would not pass). AlignmentResult::robust_used says when it was adopted; the reported residual is then
// the trimmed one.
//
// RESIDUAL. The reported residual is the RMS over the window of the compensated error in (1),
//     r = sqrt( (1/N) sum_u [alpha I(s u + d) + beta - T(u)]^2 ),
// measured at level 0 after convergence, in grey levels of the pre-smoothed REFERENCE (input images are
// 0..255). It is taken from the error image of the last Gauss-Newton iteration (with its contrast step
// applied), i.e. at the geometry before the last step, which moved no window corner by more than
// `convergence_epsilon`: re-sampling the window at the final state would cost as much as an iteration. A track is
// rejected when r exceeds `max_residual` (R; the paper uses R = 6 at 320x240 with its smoothing; with the default
// pre-smoothing sigma = 0.5 px, accepted tracks on KITTI 07 have a median r of 2.9 grey levels), when the RMS of the
// worst 3x3 block of the window exceeds `max_block_residual` (a partial occluder), or when the optimisation fails (not
// converged, window leaves the image, scale or gain out of range, flat reference).
//
// All positions are level-0 pixels of the images given (centre of the top-left pixel = (0, 0)); no camera
// model is involved, so any camera works.

#include <Eigen/Core>
#include <algorithm>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "retrace/feature/image_pyramid.h"
#include "retrace/util/types.h"

namespace retrace {

struct AlignmentOptions {
  // Side of the square reference window in pixels (odd). Segvic 2009, §6.3: 15x15.
  int window_size = 15;
  // Gauss-Newton iterations allowed at each coarse level.
  int max_iterations_coarse = 8;
  // Gauss-Newton iterations allowed at level 0; not converging within them rejects the track.
  int max_iterations_fine = 15;
  // Convergence: largest displacement of a window corner caused by the last step, in pixels of the level.
  double convergence_epsilon = 0.01;
  // The same on the coarse levels, which only have to bring the window into the basin of the next level.
  double convergence_epsilon_coarse = 0.01;
  // Sample spacing (level-0 pixels) of the wider window of the final refinement: window_size^2 samples
  // spanning stride (window_size - 1) + 1 pixels (29 px for 15x15 and 2). 0 or 1: no refinement. See above.
  int scale_window_stride = 3;
  // Gauss-Newton iterations allowed for the final refinement; not converging within them rejects the track.
  int max_iterations_scale_window = 10;
  // The final refinement is adopted only if it moves the position by at most this (level-0 pixels).
  double max_scale_window_shift = 0.5;
  // R: largest accepted RMS residual (grey levels of the pre-smoothed reference, after gain/bias
  // compensation). Segvic 2009, §5.1.1 uses R = 6 at its smoothing.
  double max_residual = 6.0;
  // Largest accepted RMS residual of the worst of the 3x3 blocks of the window (same units): a partial
  // occluder raises one block far above the window's RMS. 2 R by default: on KITTI 07 (full resolution) 99 %
  // of accepted tracks stay below 11.
  double max_block_residual = 12.0;
  // Accepted range of the scale s of the current appearance relative to the reference.
  double min_scale = 0.5;
  double max_scale = 2.0;
  // Accepted range of the gain alpha (multiplies the current image to match the reference).
  double min_gain = 0.25;
  double max_gain = 4.0;
  // Initialise gain and bias from the mean and standard deviation of the window at the coarsest level instead
  // of from the initial warp (robust to large contrast changes, e.g. between teach and repeat).
  bool contrast_from_moments = true;
  // Estimate the scale at level 0 only (translation and contrast on the coarser levels): more robust far from
  // the solution; the scale changes between frames are small.
  bool coarse_translation_only = true;
  // Sample the image with cubic (Keys) instead of bilinear interpolation at level 0: removes the
  // sub-pixel-phase dependent blur of bilinear sampling that biases scale and position by a few hundredths of
  // a pixel.
  bool cubic_interpolation = true;
  // If > 0: Gaussian prior on log(scale / initial scale) with this standard deviation, weighed against the
  // squared residuals as if their noise were 1 grey level per pixel. Windows whose scale is weakly determined
  // (the scale then trades off against the position) keep their initial scale instead of wandering; strongly
  // textured windows are hardly affected. 0 = no prior (pure least squares).
  double scale_prior_sigma = 0.0;
  // AFFINE FALLBACK (see the header): when the alignment at level 0 converges with its residual above R but within
  // 1.5 R, the geometric part is re-estimated as a full affine map x = A u + d from where it ended, and adopted when
  // that converges within `max_affine_shift` level-0 pixels of it with a residual within the limits, the singular
  // values of A in [min_scale, max_scale] and their ratio at most `max_affine_anisotropy`. Off by default (the
  // paper's warp alone); `repeat --affine` turns it on for the localizer (LocalizerOptions::affine_fallback), whose
  // references come from key-images taught from another viewpoint.
  bool affine_fallback = false;
  // AFFINE REFINEMENT (see the header): an alignment accepted under the paper's warp at level 0 is refined from there
  // with the affine warp, adopted under the same conditions as the fallback's (converged within `max_affine_shift`
  // of where it started, residuals within the limits, A's singular values in the scale range and their ratio at most
  // `max_affine_anisotropy`): the paper's isotropic warp fitted to a foreshortened or sheared window converges at a
  // shifted centre, within R. Off by default here; the localizer turns it on for its tracked features
  // (LocalizerOptions::affine_refinement; `repeat --no-affine-refine` turns it off).
  bool affine_refinement = false;
  double max_affine_anisotropy = 1.6;
  double max_affine_shift = 2.0;
  int max_iterations_affine = 15;
  // Convergence of the affine warp (largest corner displacement of the last step, level-0 pixels), as
  // `convergence_epsilon`. Looser is cheaper but not free: at 0.05 px the synthetic shear of feature_tracker_test is
  // aligned as closely (median error 0.027 against 0.026 px) and kitti07's refined repeat at 320 px counted 3.82 G
  // instructions against 4.04 G (bench_repeat_repeat), but over the validation matrix with `repeat
  // --guided-matching 20 --affine-refine --placed-start-fine` 34 tracking frames were one arc off against 23
  // (calibration 99.86 % against 99.91 %; README, "The three together", 2026-12-02).
  double convergence_epsilon_affine = 0.01;
  // ROBUST FALLBACK (see the header): an alignment that ends above R at level 0 is run again there with Tukey's
  // biweight at `robust_threshold_factor` R per pixel, and adopted when the `robust_min_inlier_fraction` of its pixels
  // with the smallest errors have an RMS within R and hold at least `robust_min_information_share` of the window's
  // information on position and scale in its weakest direction. c = 3 R is Tukey's 95 %-efficient 4.685 sigma for a
  // pixel noise of 0.64 R; 0.7: up to 30 % of the window may lie on another surface; 0.3: those pixels must not be
  // all that positions the window (an edge's aperture). Chosen over the validation matrix (README, "Robust
  // relocalization"): 0.7 / 0.7 and 0.8 / 0.5 localized fewer frames, and starting from the initial position instead of
  // where the coarse levels ended did not help.
  bool robust_fallback = false;
  double robust_min_inlier_fraction = 0.7;
  double robust_min_information_share = 0.3;
  double robust_threshold_factor = 3.0;

  bool Check() const;
};

// Why an alignment ended. Everything except kTracked rejects the track.
enum class TrackStatus : uint8_t {
  kTracked = 0,        // converged with residual <= R
  kResidualTooLarge,   // converged but the appearance differs from the reference (occlusion, wrong match)
  kNotConverged,       // no convergence within the iterations of level 0
  kOutOfImage,         // the window left the image at level 0
  kScaleOutOfRange,    // s left [min_scale, max_scale]
  kGainOutOfRange,     // alpha left [min_gain, max_gain]
  kFarFromPrediction,  // RefinePrediction only: converged too far from the prediction or its scale
  kDegenerate,         // flat reference window or singular normal equations
};
std::string TrackStatusName(TrackStatus status);

// The warp (1) between a reference and an image: x_image = scale * u + position for window offsets u, and
// gain * I + bias ~ T.
struct WarpState {
  Vector2d position = Vector2d::Zero();  // level-0 pixels in the current image
  double scale = 1.0;
  double gain = 1.0;  // alpha
  double bias = 0.0;  // beta, grey levels
};

struct AlignmentResult {
  WarpState warp;
  double residual = 0.0;  // RMS of the compensated error (see above); +inf when never evaluated at level 0
  double block_residual = 0.0;  // the same RMS over the worst of the 3x3 blocks of the window
  bool converged = false;
  bool scale_window_used = false;  // the final refinement on the larger window was adopted
  bool affine_used = false;        // adopted from the affine fallback (warp.scale is then sqrt(det A))
  bool robust_used = false;        // adopted from the robust fallback (residual: the trimmed RMS)
  int iterations = 0;              // total over all levels
  TrackStatus status = TrackStatus::kDegenerate;
  bool ok() const { return status == TrackStatus::kTracked; }
};

// The stored reference appearance of one feature: the window cut at every pyramid level around a position,
// with the precomputed Jacobian rows and inverse Gauss-Newton matrix of the inverse-compositional alignment.
class ReferencePatch {
 public:
  ReferencePatch() = default;

  // Cuts the reference around `position` (level-0 pixels; cubic interpolation at level 0, bilinear on the
  // coarse levels) from `pyramid`, on up to `max_levels` levels, plus the wide level-0 window of the final
  // refinement with `scale_window_stride` (0 or 1: none; also none when it does not fit in the image). Coarse levels
  // where the window (plus a one-pixel gradient border) does not fit or is flat are dropped. Returns false (and leaves
  // the patch empty) when even level 0 is unusable. The wide window is cut at its first use (ScaleWindowStride) from
  // level 0 as it is at Create: `image` kKept when the pyramid's level 0 is never written again (a key-image's pyramid,
  // built once: the patch keeps a handle to it), kTransient otherwise (a frame's pyramid, rebuilt in place for the next
  // frame: the patch copies the 49 x 49 pixels it needs).
  enum class PatchImage { kTransient, kKept };
  bool Create(const ImagePyramid& pyramid, const Vector2d& position, int window_size = 15, int max_levels = 3,
              int scale_window_stride = AlignmentOptions().scale_window_stride,
              PatchImage image = PatchImage::kTransient);

  bool Valid() const { return num_levels_ > 0; }
  int NumLevels() const { return num_levels_; }
  int WindowSize() const { return window_size_; }
  // Where the reference was cut (level-0 pixels of the reference image).
  const Vector2d& Position() const { return position_; }
  // Row-major window_size^2 grey values of the (pre-smoothed) reference at `level` minus their mean
  // Mean(level).
  const float* Centered(int level) const { return data_.data() + Offset(level); }
  double Mean(int level) const { return mean_[level]; }
  // Mean and standard deviation of the level-0 window (useful to judge a reference's contrast).
  double StdDev() const { return std_dev_; }

  // Precomputed data of the alignment, per level: gradients Tx, Ty, u.grad T (window_size^2 floats each) and
  // the inverse 5x5 Gauss-Newton matrix of (dx, dy, ds, lambda, delta).
  const float* Gx(int level) const { return Centered(level) + window_size_ * window_size_; }
  const float* Gy(int level) const { return Centered(level) + 2 * window_size_ * window_size_; }
  const float* Gs(int level) const { return Centered(level) + 3 * window_size_ * window_size_; }
  const Eigen::Matrix<float, 5, 5>& InverseHessian(int level) const { return inverse_hessian_[level]; }
  // The same with the scale fixed (row and column of ds zero).
  const Eigen::Matrix<float, 5, 5>& InverseHessianTranslation(int level) const {
    return inverse_hessian_translation_[level];
  }
  // The larger level-0 window of the final refinement (0 when it was not requested, does not fit in the image
  // or is badly conditioned): values minus their mean, Tx, Ty, u.grad T, and its inverse Gauss-Newton matrix.
  // Cut at the first call of ScaleWindowStride(); the other three hold it only after that call (the same thread rule as
  // AffineInverseHessian).
  int ScaleWindowStride() const {
    if (!scale_source_.empty()) CutScaleWindow();
    return scale_window_stride_;
  }
  const float* ScaleWindow() const { return scale_data_.data(); }
  double ScaleWindowMean() const { return scale_mean_; }
  const Eigen::Matrix<float, 5, 5>& ScaleWindowInverseHessian() const { return scale_inverse_hessian_; }
  const Eigen::Matrix<float, 5, 5>& ScaleWindowInverseHessianTranslation() const {
    return scale_inverse_hessian_translation_;
  }
  // The inverse 8x8 Gauss-Newton matrix of the affine warp at level 0 (parameters of A, d, lambda, delta; the affine
  // fallback and refinement), computed at its first use and kept with the patch (and its copies); null when it is
  // singular or badly conditioned. The first call writes the cache: make it before the patch is shared between
  // threads (a Localizer's patches are used by its own thread only).
  using AffineMatrix = Eigen::Matrix<double, 8, 8, Eigen::DontAlign>;
  const AffineMatrix* AffineInverseHessian() const;

 private:
  size_t Offset(int level) const { return static_cast<size_t>(level) * 4 * window_size_ * window_size_; }

  int window_size_ = 0;
  int num_levels_ = 0;
  Vector2d position_ = Vector2d::Zero();
  double std_dev_ = 0.0;
  // Per level: centred values T - mean, Tx, Ty, u.grad T, each window_size^2 floats.
  std::vector<float> data_;
  // Per level: mean grey value of the window.
  std::vector<double> mean_;
  // Per level: H0^-1 of the 5 parameters (dx, dy, ds, lambda, delta).
  std::vector<Eigen::Matrix<float, 5, 5>, Eigen::aligned_allocator<Eigen::Matrix<float, 5, 5>>>
      inverse_hessian_;
  std::vector<Eigen::Matrix<float, 5, 5>, Eigen::aligned_allocator<Eigen::Matrix<float, 5, 5>>>
      inverse_hessian_translation_;
  // Cuts the level-0 window of the final refinement from scale_source_ (ScaleWindowStride's first call).
  void CutScaleWindow() const;

  // The level-0 window of the final refinement, cut at its first use: pending while scale_source_ holds level 0 or
  // the part of it the window samples (at scale_source_origin_ of an image of scale_image_size_; the stride is then
  // the one requested), emptied by the cut.
  mutable cv::Mat scale_source_;
  cv::Point scale_source_origin_;
  cv::Size scale_image_size_;
  mutable int scale_window_stride_ = 0;
  mutable std::vector<float> scale_data_;
  mutable double scale_mean_ = 0.0;
  mutable Eigen::Matrix<float, 5, 5> scale_inverse_hessian_ = Eigen::Matrix<float, 5, 5>::Zero();
  mutable Eigen::Matrix<float, 5, 5> scale_inverse_hessian_translation_ = Eigen::Matrix<float, 5, 5>::Zero();
  // AffineInverseHessian's cache: 0 not computed yet, 1 valid, -1 singular.
  mutable int affine_state_ = 0;
  mutable AffineMatrix affine_inverse_hessian_;
};

// Aligns `reference` to the image in `pyramid` by minimising (1), starting from `initial` (level-0 pixels),
// coarse to fine from the coarsest level shared by the pyramid and the reference on which the window fits.
AlignmentResult AlignToReference(const ImagePyramid& pyramid, const ReferencePatch& reference,
                                 const WarpState& initial, const AlignmentOptions& options);

struct RefinePredictionOptions {
  AlignmentOptions alignment;
  // Accept only when the converged position is within this distance (level-0 pixels) of the prediction.
  double max_distance = 3.0;
  // Accept only when converged scale / initial scale lies in [1 / max_scale_ratio, max_scale_ratio].
  double max_scale_ratio = 1.25;

  bool Check() const { return alignment.Check() && max_distance > 0.0 && max_scale_ratio >= 1.0; }
};

// Refines a PREDICTED position (e.g. from point transfer) against a stored reference, starting at the
// prediction with `initial_scale` (distance of the 3D point to the reference viewpoint / its distance to the
// current pose, Segvic 2009 §5.2.1). Accepted (status kTracked) only if it converges near the predicted
// position and scale with a residual <= R; otherwise a normal rejected result is returned.
AlignmentResult RefinePrediction(const ImagePyramid& pyramid, const ReferencePatch& reference,
                                 const Vector2d& predicted_position, double initial_scale,
                                 const RefinePredictionOptions& options);

inline AlignmentOptions DefaultTrackingAlignment() {
  AlignmentOptions options;
  options.scale_prior_sigma = 0.02;
  return options;
}

struct FeatureTrackerOptions {
  // Alignment of each feature to its reference. Frame to frame the scale changes little, so tracking uses a
  // scale prior (std 2 % per frame around the previous scale) that keeps weakly determined scales from
  // trading off against the position.
  AlignmentOptions alignment = DefaultTrackingAlignment();
  // Levels of the reference patches (<= the pyramid levels used when tracking).
  int num_levels = 3;
  // Start each frame from position + (last frame-to-frame displacement) instead of the last position.
  bool constant_velocity = true;
  // Features tracked in the previous frame, whose guess comes from their own velocity, start the alignment at
  // this pyramid level instead of the coarsest. Unless that alignment converges (accepted, or rejected for a
  // residual above R: the window does not match), the full coarse-to-fine alignment is run: a guess outside
  // the basin of the start level (abrupt change of motion) ends in a give-up, not in a converged mismatch.
  // Negative: always coarse to fine. Measured (instructions spent in tracking, 320x240): level 1 saves 6 % on
  // KITTI 07 and 12 % on the synthetic benchmark sequence, level 0 12 % and 25 %, with as many tracked
  // features. Level 1 by default: with level 0, the simulated repeat (repeat_sim_test: other sun, offset,
  // pedestrians) localised 3 frames two arcs away from the truth (none with level 1 or coarse to fine): the
  // coarsest level keeps windows away from look-alike structures that level 0 alone converges onto.
  // On KITTI, after a give-up at the start level half of the fallbacks succeed; after a converged mismatch
  // 0.3 % would, so those are not retried.
  int predicted_start_level = 1;
  // On: features added with a reference cut from another image (AddFeature(reference, alignment): the localizer's
  // mapped features, placed by RefinePrediction on the finest levels) start at predicted_start_level in every
  // frame, with a velocity of their own or not: only their finer windows were checked against the current view, and
  // their coarsest ones may see surroundings at other depths, onto which they slide (standing still after a
  // relocalization in the simulated town, 16 of 19 such features were lost in the next frame; feature_tracker_test
  // FeaturePlacedFromAnotherViewKeepsItsFineAlignment). Off by default here (teach places no feature from another
  // image); the localizer turns it on with the affine refinement (LocalizerOptions::tracker, affine_refinement):
  // alone, on the 42 closed-loop drives it keeps seed6 on its map (RMS 0.194 -> 0.079 m) and seed3's start from
  // 1.5 m converges, but over the validation matrix it tracks more frames 2-3 m beside the path and more of them one
  // arc behind (README, "Features placed from a key-image").
  bool placed_features_start_fine = false;
  // Features added from a robust alignment (AlignmentResult::robust_used: a window straddling two surfaces lit
  // differently) are tracked with the robust fallback on (the same window keeps straddling them); the others with
  // `alignment` as given.
  bool robust_acquired_tracking = false;

  bool Check() const { return alignment.Check() && num_levels >= 1; }
};

// One tracked feature as reported after a frame.
struct TrackedFeature {
  feature_t id = kInvalidFeatureId;
  WarpState warp;               // position, scale, gain, bias in the last image
  double residual = 0.0;        // RMS residual against the reference (grey levels)
  double block_residual = 0.0;  // RMS residual of the worst 3x3 block of the window
  bool converged = false;
  TrackStatus status = TrackStatus::kTracked;
  int num_frames = 0;  // images in which the feature has been tracked since it was added (1 when added)
  // Added from an alignment the robust fallback adopted (AlignmentResult::robust_used): its window matched its
  // reference only in part, and its position may be off by a few tenths of a pixel.
  bool robust_acquired = false;
};

// Owns the features and their references and advances all of them on each new frame.
//
//   ImagePyramid pyramid(frame);                 // once per frame, shared with the detector etc.
//   tracker.Track(pyramid);                      // aligns every feature to its reference; failures are
//   removed tracker.AddFeatures(pyramid, positions);     // new features, reference cut from this frame
class FeatureTracker {
 public:
  explicit FeatureTracker(const FeatureTrackerOptions& options = {});

  // Adds a feature whose reference is cut from `pyramid` at `position`. `id` = kInvalidFeatureId assigns the
  // next free id. Returns the id, or kInvalidFeatureId when no reference can be cut there (border, flat
  // window).
  feature_t AddFeature(const ImagePyramid& pyramid, const Vector2d& position,
                       feature_t id = kInvalidFeatureId);
  // Adds one feature per position; returns the ids (kInvalidFeatureId for the rejected ones).
  std::vector<feature_t> AddFeatures(const ImagePyramid& pyramid, const std::vector<Vector2d>& positions);
  // Adds a feature with a given reference at a known warp (e.g. after RefinePrediction accepted a
  // prediction). The first form copies the reference; the second shares it (the localizer's references, cut once
  // per key-image and feature, are shared by every track that uses them: a reference is ~15 kB).
  feature_t AddFeature(const ReferencePatch& reference, const AlignmentResult& alignment,
                       feature_t id = kInvalidFeatureId);
  feature_t AddFeature(std::shared_ptr<const ReferencePatch> reference, const AlignmentResult& alignment,
                       feature_t id = kInvalidFeatureId);

  // Aligns every feature to its reference in the new image. Features whose alignment fails are removed; the
  // returned list has one entry per feature that was tracked in this call (failures included, with their
  // status).
  const std::vector<TrackedFeature>& Track(const ImagePyramid& pyramid);

  // Removes a feature; returns false when it is unknown.
  bool Remove(feature_t id);
  // Redefines the reference of a feature: cut from `pyramid` at `position` (e.g. a key-image after a
  // topological transition). The feature's warp is reset to (position, scale 1, gain 1, bias 0). Returns
  // false when unknown or when no reference can be cut there (the feature is then left unchanged). The image
  // velocity of the feature (for the constant-velocity guess) is kept: it belongs to the motion, not the reference.
  bool SetReference(feature_t id, const ImagePyramid& pyramid, const Vector2d& position);

  // Features currently tracked (all with status kTracked).
  const std::vector<TrackedFeature>& Features() const { return features_; }
  const TrackedFeature* Find(feature_t id) const;
  const ReferencePatch* Reference(feature_t id) const;
  int NumFeatures() const { return static_cast<int>(features_.size()); }
  // Features added from a robust alignment (AlignmentResult::robust_used), tracked since.
  int NumRobustFeatures() const {
    return static_cast<int>(
        std::count_if(features_.begin(), features_.end(), [](const TrackedFeature& f) { return f.robust_acquired; }));
  }
  const FeatureTrackerOptions& Options() const { return options_; }

 private:
  int IndexOf(feature_t id) const;

  FeatureTrackerOptions options_;
  feature_t next_id_ = 0;
  // Per-frame scratch space of Track(), kept to avoid allocations on the hot path.
  std::vector<AlignmentResult> scratch_results_;
  std::vector<double> scratch_dx_, scratch_dy_;
  std::vector<size_t> scratch_without_velocity_;
  std::vector<TrackedFeature> features_;
  // Shared (const: only ReferencePatch's own lazily computed affine matrix may still be filled in), so removing a
  // feature or compacting the list moves pointers, not patches.
  std::vector<std::shared_ptr<const ReferencePatch>> references_;
  std::vector<Vector2d> velocities_;
  std::vector<uint8_t> placed_;  // 1: reference cut from another image (see placed_features_start_fine)
  std::vector<TrackedFeature> last_results_;
};

}  // namespace retrace
