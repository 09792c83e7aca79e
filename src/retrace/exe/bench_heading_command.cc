// retrace bench heading: the accuracy of the heading of the planar two-view geometry (Booij 2007 §B.5.1, eq. B.4)
// over every ordered pair of frames of a sequence with ground truth whose camera centres are at least
// --min-baseline apart: the same matching and estimate as `two-view --planar` (two_view_matching.h, planar_pose.h),
// the truth φ = atan2(c_x, c_z) of B's centre c in A's camera frame (KITTI poses.txt). The paper's experiment is a
// 3 x 3 grid of positions 1 m apart with 4 orientations each; scripts/heading-grid renders it and runs this.
//
//   retrace bench heading --sequence grid --out report   →  heading_errors.csv, heading_histogram.png, a summary

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <vector>

#include <fmt/format.h>
#include <opencv2/core.hpp>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgcodecs.hpp>

#include "retrace/camera/camera_io.h"
#include "retrace/dataset/ground_truth.h"
#include "retrace/dataset/sequence.h"
#include "retrace/exe/commands.h"
#include "retrace/geometry/planar_pose.h"
#include "retrace/geometry/two_view_matching.h"
#include "retrace/util/error.h"
#include "retrace/util/progress.h"
#include "retrace/util/statistics.h"
#include "retrace/viz/plot.h"

namespace retrace {
namespace {

struct HeadingArguments {
  std::filesystem::path sequence;
  std::filesystem::path out;
  double min_baseline = 0.5;
  double ratio = TwoViewMatchingOptions().ratio;
  double histogram_range_mrad = 40.0;
  bool quiet = false;
};

struct PairHeading {
  size_t a = 0, b = 0;
  double truth = 0.0;
  bool has_estimate = false;
  double estimate = 0.0;
  int inliers = 0;
  double error() const { return std::remainder(estimate - truth, 2 * M_PI); }
};

void RunHeadingBench(const HeadingArguments& args) {
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_ERROR);
  std::unique_ptr<Sequence> sequence = OpenSequence(args.sequence);
  const auto truth_file = sequence->ground_truth_file();
  if (!truth_file || truth_file->filename() != "poses.txt") {
    throw InputError(args.sequence.string(), "needs KITTI ground-truth poses (poses.txt)");
  }
  const auto calibration = sequence->calibration_file();
  if (!calibration) throw InputError(args.sequence.string(), "has no camera calibration (camera.yaml or calib.txt)");
  const std::vector<TimedPose> poses = ReadKittiPoses(*truth_file);
  std::vector<cv::Mat> images;
  while (auto frame = sequence->Next()) images.push_back(frame->image);
  if (images.size() != poses.size()) {
    throw InputError(truth_file->string(), fmt::format("{} poses for {} frames", poses.size(), images.size()));
  }
  const std::unique_ptr<CameraModel> camera =
      ReadCameraFile(*calibration, images.front().size(), sequence->calibration_camera());

  std::vector<PairHeading> pairs;
  for (size_t a = 0; a < images.size(); ++a) {
    for (size_t b = 0; b < images.size(); ++b) {
      const Rigid3d& pose_a = poses[a].world_from_cam;
      const Vector3d c = pose_a.rotation.transpose() * (poses[b].world_from_cam.translation - pose_a.translation);
      if (a == b || c.norm() < args.min_baseline) continue;
      PairHeading pair;
      pair.a = a;
      pair.b = b;
      pair.truth = std::atan2(c.x(), c.z());  // eq. (B.4) in retrace's axes, as PlanarHeading
      pairs.push_back(pair);
    }
  }
  if (pairs.empty()) {
    throw InputError(args.sequence.string(), fmt::format("no two frames are {} m apart", args.min_baseline));
  }

  TwoViewMatchingOptions matching;
  matching.ratio = args.ratio;
  ProgressBar progress("heading", pairs.size(), !args.quiet);
  const int chunk = 4 * std::max(1, cv::getNumThreads());  // pairs in parallel between two progress updates
  for (int first = 0; first < static_cast<int>(pairs.size()); first += chunk) {
    const int last = std::min<int>(first + chunk, pairs.size());
    cv::parallel_for_(cv::Range(first, last), [&](const cv::Range& range) {
      for (int i = range.start; i < range.end; ++i) {
        PairHeading& pair = pairs[i];
        std::vector<Vector3d> bearings_a, bearings_b;
        MatchesToBearings(MatchTwoViewFeatures(images[pair.a], images[pair.b], matching), *camera, *camera,
                          &bearings_a, &bearings_b);
        const TwoViewGeometry g = EstimatePlanarRelativePose(bearings_a, bearings_b, camera->FocalLength());
        pair.has_estimate = g.success;
        pair.inliers = g.num_inliers;
        if (g.success) pair.estimate = PlanarHeading(g.b_from_a);
      }
    });
    progress.Advance(last - first);
  }
  progress.Finish();

  std::filesystem::create_directories(args.out);
  const std::filesystem::path csv_path = args.out / "heading_errors.csv";
  std::ofstream csv(csv_path);
  csv << "frame_a,frame_b,true_heading,heading,error,inliers\n";
  std::vector<double> errors, magnitudes;
  for (const PairHeading& pair : pairs) {
    csv << fmt::format("{},{},{:.6f},", pair.a, pair.b, pair.truth);
    if (pair.has_estimate) {
      csv << fmt::format("{:.6f},{:.6f},{}\n", pair.estimate, pair.error(), pair.inliers);
      errors.push_back(pair.error());
      magnitudes.push_back(std::abs(pair.error()));
    } else {
      csv << fmt::format(",,{}\n", pair.inliers);
    }
  }
  csv.flush();
  if (!csv) throw InputError(csv_path.string(), "cannot be written");
  if (errors.empty()) throw InputError(args.sequence.string(), "no pair of frames gave a planar geometry");

  double mean = 0.0, variance = 0.0;
  for (double e : errors) mean += e / errors.size();
  for (double e : errors) variance += (e - mean) * (e - mean) / errors.size();
  const double deviation = std::sqrt(variance);
  std::cout << fmt::format(
      "{} pairs at least {} m apart, {} without a geometry; heading error: mean {:.4f} rad, standard deviation "
      "{:.4f} rad, median |error| {:.4f}, 95th percentile {:.4f}, max {:.4f} rad\n",
      pairs.size(), args.min_baseline, pairs.size() - errors.size(), mean, deviation, Quantile(magnitudes, 0.5),
      Quantile(magnitudes, 0.95), Quantile(magnitudes, 1.0));

  // Histogram in 1 mrad bins; errors beyond the range land in the outermost bins (counted in the title).
  const int half = static_cast<int>(std::ceil(args.histogram_range_mrad));
  PlotSeries bars;
  bars.style = PlotSeries::Style::kBars;
  bars.label = "pairs per 1 mrad";
  for (int bin = -half; bin < half; ++bin) {
    bars.x.push_back(bin + 0.5);
    bars.y.push_back(0.0);
  }
  int beyond = 0;
  for (double e : errors) {
    const double mrad = 1000.0 * e;
    beyond += std::abs(mrad) >= half;
    const int bin = std::clamp(static_cast<int>(std::floor(mrad)), -half, half - 1);
    bars.y[bin + half] += 1.0;
  }
  PlotOptions plot;
  plot.title = fmt::format("planar heading error, {} pairs: std {:.1f} mrad, mean {:.1f} mrad ({} beyond +-{} mrad)",
                           errors.size(), 1000 * deviation, 1000 * mean, beyond, half);
  plot.x_label = "heading error (mrad)";
  plot.y_label = "pairs";
  plot.x_min = -half;
  plot.x_max = half;
  plot.y_min = 0.0;
  const std::filesystem::path png = args.out / "heading_histogram.png";
  if (!cv::imwrite(png.string(), RenderPlot({bars}, plot))) throw InputError(png.string(), "cannot be written");
  std::cout << fmt::format("wrote {} and {}\n", csv_path.string(), png.string());
}

}  // namespace

void RegisterBenchHeadingCommand(CLI::App* bench) {
  auto args = std::make_shared<HeadingArguments>();
  CLI::App* cmd = bench->add_subcommand(
      "heading", "Heading accuracy of the planar two-view geometry (Booij 2007 eq. B.4) over all pairs of a sequence "
                 "with ground truth: CSV, histogram PNG, statistics");
  cmd->add_option("--sequence", args->sequence, "Sequence with KITTI poses.txt and a camera (e.g. `sim render --poses`)")
      ->required();
  cmd->add_option("--out", args->out, "Folder for heading_errors.csv and heading_histogram.png")->required();
  cmd->add_option("--min-baseline", args->min_baseline, "Pairs whose camera centres are closer (m) are skipped")
      ->check(CLI::Range(0.0, 1e6))->capture_default_str();
  cmd->add_option("--ratio", args->ratio, "Lowe's ratio of the SIFT matches (as two-view --ratio)")
      ->check(CLI::Range(0.01, 1.0))->capture_default_str();
  cmd->add_option("--histogram-range", args->histogram_range_mrad, "Half width of the histogram (mrad)")
      ->check(CLI::Range(1.0, 3142.0))->capture_default_str();
  cmd->add_flag("--quiet", args->quiet, "No progress bar");
  cmd->callback([args]() { RunHeadingBench(*args); });
}

}  // namespace retrace
