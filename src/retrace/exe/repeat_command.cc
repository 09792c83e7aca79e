// retrace repeat: localize every frame of a drive in a taught map and steer (Segvic 2009 §5.2, §6.3; design §6).
//
// Writes one CSV row per input frame (flushed as written, so a live run can be followed with `tail -f`):
//   frame,image,timestamp,state,arc,node_from,node_to,tracked,tracked_previous,tracked_current,tracked_next,
//   resumed,rejected,dropped,drifted,redefined,sigma_p,sigma_p_from,sigma_p_to,position_on_arc,transition,steering,ms,
//   position_via_from,position_via_to,position_via_pose,sigma_p_pose,pose_inliers,key_images_matched,confidence,
//   evidence,belief_arc,lateral_m,lateral_sigma_m,heading_error_rad,along_m,to_next_m,curvature_ahead,
//   frame_lateral_m,frame_lateral_sigma_m,heading_sigma_rad,along_sigma_m,heading_per_lateral
// frame = 0-based index in the input sequence (after --every/--offset), state = tracking | lost | relocalizing,
// node ids and arc -1 when not tracking, σ_p columns -1 when not estimated, ms = processing time of the frame,
// position_on_arc the belief's position along the arc (0 at node_from, 1 at node_to), the position_via_* columns
// this frame's placements (W_t:a, W_t:b, the absolute pose in the arc's reconstruction; empty when that estimate
// gave none), key_images_matched the key-images verified by wide-baseline matching in a bootstrap or relocalization
// frame (0 otherwise), confidence the belief's probability that the camera is on the reported arc (in lost frames:
// on the arc it finds most likely, belief_arc), evidence 1 when this frame gave the belief a placement it accepts;
// the last ten (repeat/taught_path.h; empty unless the camera's height is known and the frame's absolute pose is
// usable): the camera's signed distance from the taught path in metres (positive to the right in the direction of
// travel; the recent frames' combined, LocalizerOptions::lateral_filter) and its standard deviation, the optical
// axis against the path's tangent (radians, positive to the right), the distance along the path from node_from and
// left to node_to (m), the sharpest curvature ahead (1/m, positive to the left), this frame's own distance from the
// path and its standard deviation, and the standard deviations of the heading error and of along_m.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <string>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include "retrace/camera/camera_checks.h"
#include "retrace/camera/camera_io.h"
#include "retrace/dataset/ground_truth.h"
#include "retrace/dataset/sequence.h"
#include "retrace/exe/commands.h"
#include "retrace/exe/sequence_input.h"
#include "retrace/image/image_utils.h"
#include "retrace/map/map_database.h"
#include "retrace/repeat/evaluation.h"
#include "retrace/repeat/localizer.h"
#include "retrace/repeat/map_loading.h"
#include "retrace/util/error.h"
#include "retrace/util/memory_usage.h"
#include "retrace/util/progress.h"
#include "retrace/util/statistics.h"
#include "retrace/viz/plot.h"

namespace retrace {
namespace {

// A number with 4 decimals, or empty when not a number (an estimate that gave none).
std::string OptionalNumber(double value) { return std::isfinite(value) ? fmt::format("{:.4f}", value) : ""; }

struct RepeatArguments {
  std::filesystem::path map;
  std::filesystem::path sequence;
  BagInput bag;
  std::filesystem::path camera;
  std::filesystem::path output;
  std::filesystem::path overlay;
  arc_t start_arc = kInvalidArcId;
  size_t every = 1;
  size_t offset = 0;
  bool evaluate = false;
  bool no_progress = false;
  LocalizerOptions options;
};

const cv::Scalar kRoleColors[3] = {cv::Scalar(200, 120, 0), cv::Scalar(0, 200, 0), cv::Scalar(0, 160, 255)};

cv::Mat DrawOverlay(const cv::Mat& gray, const FrameResult& result) {
  cv::Mat image;
  cv::cvtColor(gray, image, cv::COLOR_GRAY2BGR);
  const int half = std::max(3, gray.cols / 200);
  for (const FeatureMark& mark : result.marks) {
    const cv::Point p(static_cast<int>(std::lround(mark.position.x())),
                      static_cast<int>(std::lround(mark.position.y())));
    const cv::Scalar color = kRoleColors[static_cast<int>(mark.role)];
    if (mark.tracked) {
      cv::rectangle(image, p - cv::Point(half, half), p + cv::Point(half, half), color, 1);
    } else {
      cv::line(image, p - cv::Point(half, half), p + cv::Point(half, half), cv::Scalar(0, 0, 255), 1);
      cv::line(image, p - cv::Point(half, -half), p + cv::Point(half, -half), cv::Scalar(0, 0, 255), 1);
    }
  }
  std::string text = fmt::format("frame {}  {}", result.frame_index, LocalizerStateName(result.state));
  if (result.state == LocalizerState::kTracking) {
    text += fmt::format("  arc {} ({}->{})  tracked {}  steering {:+.3f}", result.arc, result.node_from,
                        result.node_to, result.tracked, result.steering);
  }
  cv::putText(image, text, cv::Point(8, 20), cv::FONT_HERSHEY_SIMPLEX, 0.55, cv::Scalar(0, 0, 0), 3);
  cv::putText(image, text, cv::Point(8, 20), cv::FONT_HERSHEY_SIMPLEX, 0.55, cv::Scalar(255, 255, 255), 1);
  return image;
}

// The reported arc against the true one per frame (indices along the route): where a person sees at a glance
// whether the localizer followed the route, where it was lost and where it was wrong.
void WriteTruthPlot(const std::vector<FrameResult>& results, const TopologicalEvaluation& evaluation,
                    const std::filesystem::path& path) {
  PlotSeries truth, correct, wrong, lost;
  truth.label = "true arc";
  truth.color = cv::Scalar(160, 160, 160);
  truth.thickness = 6;
  correct.label = "reported, correct";
  wrong.label = "reported, wrong";
  lost.label = "lost / relocalizing";
  correct.color = cv::Scalar(60, 160, 40);
  wrong.color = cv::Scalar(0, 0, 220);
  lost.color = cv::Scalar(0, 140, 255);
  for (PlotSeries* s : {&correct, &wrong, &lost}) {
    s->style = PlotSeries::Style::kPoints;
    s->thickness = 2;
  }
  for (size_t i = 0; i < results.size() && i < evaluation.per_frame.size(); ++i) {
    const FrameTruth& t = evaluation.per_frame[i];
    const double x = static_cast<double>(results[i].frame_index);
    truth.x.push_back(x);
    truth.y.push_back(t.true_arc_index);
    PlotSeries& s = t.lost ? lost : (t.correct ? correct : wrong);
    s.x.push_back(x);
    s.y.push_back(t.lost ? -1.0 : t.estimated_arc_index);
  }
  PlotOptions options;
  options.title = "repeat: reported arc against topological ground truth (lost drawn at -1)";
  options.x_label = "frame";
  options.y_label = "arc index along the route";
  if (!cv::imwrite(path.string(), RenderPlot({truth, correct, wrong, lost}, options))) {
    throw InputError(path.string(), "cannot be written");
  }
}

// The position along the reported arc (0 at its first key-image, 1 at its second; a transition at 1) against the
// true camera centre projected on the same arc, per frame: how early or late transitions are, and how far each
// estimate places the camera.
void WritePositionPlot(const std::vector<FrameResult>& results, const TopologicalEvaluation& evaluation,
                       const std::filesystem::path& path) {
  PlotSeries truth, fused, pose;
  truth.label = "true position on the reported arc";
  truth.color = cv::Scalar(160, 160, 160);
  truth.thickness = 5;
  fused.label = "position used for transitions";
  fused.color = cv::Scalar(60, 160, 40);
  pose.label = "absolute pose in the arc's reconstruction";
  pose.color = cv::Scalar(200, 120, 0);
  for (PlotSeries* s : {&truth, &fused, &pose}) s->style = PlotSeries::Style::kPoints;
  fused.thickness = 2;
  pose.thickness = 1;
  for (size_t i = 0; i < results.size() && i < evaluation.per_frame.size(); ++i) {
    const FrameResult& r = results[i];
    const double x = static_cast<double>(r.frame_index);
    const double t = evaluation.per_frame[i].true_position_on_arc;
    // After a transition the positions of that frame refer to the arc left; the truth to the arc reached.
    if (r.transition != 0) continue;
    if (std::isfinite(t)) {
      truth.x.push_back(x);
      truth.y.push_back(t);
    }
    if (r.state == LocalizerState::kTracking && r.position_valid) {
      fused.x.push_back(x);
      fused.y.push_back(r.position_on_arc);
    }
    if (r.state == LocalizerState::kTracking && std::isfinite(r.position_via_pose)) {
      pose.x.push_back(x);
      pose.y.push_back(r.position_via_pose);
    }
  }
  PlotOptions options;
  options.title = "repeat: position along the reported arc against ground truth";
  options.x_label = "frame";
  options.y_label = "position on the arc (arc lengths)";
  options.y_min = -0.5;
  options.y_max = 1.5;
  if (!cv::imwrite(path.string(), RenderPlot({truth, fused, pose}, options))) {
    throw InputError(path.string(), "cannot be written");
  }
}

// The belief's confidence per frame against correctness: frames reported `tracking` on the true arc, on a wrong arc,
// and frames reported lost (at the confidence of the arc the belief found most likely). A calibrated belief puts
// wrong frames below the tracking threshold.
void WriteConfidencePlot(const std::vector<FrameResult>& results, const TopologicalEvaluation& evaluation,
                         double threshold, const std::filesystem::path& path) {
  PlotSeries correct, wrong, lost;
  correct.label = "tracking, correct arc";
  correct.color = cv::Scalar(60, 160, 40);
  wrong.label = "tracking, wrong arc";
  wrong.color = cv::Scalar(0, 0, 220);
  lost.label = "lost (confidence of the most likely arc)";
  lost.color = cv::Scalar(160, 160, 160);
  for (PlotSeries* s : {&correct, &wrong, &lost}) {
    s->style = PlotSeries::Style::kPoints;
    s->thickness = 3;
  }
  for (size_t i = 0; i < results.size() && i < evaluation.per_frame.size(); ++i) {
    const FrameTruth& t = evaluation.per_frame[i];
    PlotSeries& series = t.lost ? lost : (t.correct ? correct : wrong);
    series.x.push_back(static_cast<double>(results[i].frame_index));
    series.y.push_back(results[i].confidence);
  }
  PlotOptions options;
  options.title = "repeat: the belief's confidence against ground truth";
  options.x_label = "frame";
  options.y_label = "confidence";
  options.y_min = 0.0;
  options.y_max = 1.4;  // room for the legend above the confident frames
  options.reference_lines.push_back({threshold, "tracking threshold"});
  if (!cv::imwrite(path.string(), RenderPlot({correct, wrong, lost}, options))) {
    throw InputError(path.string(), "cannot be written");
  }
}

// The metric offset from the taught path per frame against ground truth: the reported one (the recent frames
// combined) and each frame's own, where a person sees runs of frames a metre off and whether the combination
// outvoted them. `truth[i]` is the true offset of results[i] (NaN where unknown).
void WriteLateralPlot(const std::vector<FrameResult>& results, const std::vector<double>& truth,
                      const std::filesystem::path& path) {
  OffsetPlotSeries series = MakeOffsetPlotSeries("lateral_m (recent frames combined)");
  PlotSeries &true_offset = series.truth, &combined = series.combined, &own = series.own;
  for (size_t i = 0; i < results.size() && i < truth.size(); ++i) {
    const double x = static_cast<double>(results[i].frame_index);
    if (std::isfinite(truth[i])) {
      true_offset.x.push_back(x);
      true_offset.y.push_back(truth[i]);
    }
    if (results[i].path.valid) {
      combined.x.push_back(x);
      combined.y.push_back(results[i].path.lateral_m);
      own.x.push_back(x);
      own.y.push_back(results[i].path.frame_lateral_m);
    }
  }
  PlotOptions options;
  options.title = "repeat: offset from the taught path against ground truth (positive: right)";
  options.x_label = "frame";
  options.y_label = "lateral offset (m)";
  if (!cv::imwrite(path.string(), RenderPlot({true_offset, own, combined}, options))) {
    throw InputError(path.string(), "cannot be written");
  }
}

void WriteTrackedPlot(const std::vector<FrameResult>& results, const std::filesystem::path& path) {
  std::map<arc_t, PlotSeries> by_arc;
  PlotSeries lost;
  lost.label = "lost / relocalizing";
  lost.style = PlotSeries::Style::kPoints;
  lost.color = cv::Scalar(0, 0, 220);
  lost.thickness = 3;
  for (const FrameResult& r : results) {
    if (r.state != LocalizerState::kTracking) {
      lost.x.push_back(static_cast<double>(r.frame_index));
      lost.y.push_back(0.0);
      continue;
    }
    PlotSeries& series = by_arc[r.arc];
    if (series.label.empty()) {
      series.label = fmt::format("arc {}", r.arc);
      series.style = PlotSeries::Style::kPoints;
      series.color = SeriesColor(static_cast<int>(by_arc.size()) - 1);
      series.thickness = 3;
    }
    series.x.push_back(static_cast<double>(r.frame_index));
    series.y.push_back(r.tracked);
  }
  std::vector<PlotSeries> series;
  for (auto& [arc, s] : by_arc) series.push_back(std::move(s));
  if (!lost.x.empty()) series.push_back(std::move(lost));
  PlotOptions options;
  options.title = "repeat: tracked features per frame, coloured by arc";
  options.x_label = "frame";
  options.y_label = "tracked features";
  options.y_min = 0.0;
  cv::imwrite(path.string(), RenderPlot(series, options));
}

// Two calibrations that image the same rays within this distance at the key-images' resolution are one camera: a
// pixel is the order of the tracker's noise, a larger difference moves every predicted feature.
constexpr double kSameCameraPx = 1.0;

// The camera the frames are localized with, at the key-images' width: the map's, or --camera when it sees the same
// rays. The key-images were measured with the map's camera, so a calibration that differs from it, or frames that
// do not have its shape, are refused rather than bent to fit (frames of the same shape at another resolution are
// resized, as teach --width did).
std::unique_ptr<CameraModel> RepeatCamera(const RepeatArguments& args, int key_width, const CameraModel* map_camera,
                                          Sequence& sequence) {
  const cv::Size frames = sequence.image_size();
  if (frames.empty()) throw InputError(args.sequence.string(), "no readable frame");
  std::unique_ptr<CameraModel> camera;
  if (!args.camera.empty()) {
    camera = ReadCameraFile(args.camera, frames, sequence.calibration_camera());
  } else {
    if (!map_camera) throw InputError(args.map.string(), "the map stores no camera; give --camera FILE");
    camera = map_camera->Clone();
  }
  // The frames' shape at the key-images' width, as ResizeToWidth makes it.
  const double factor = static_cast<double>(key_width) / frames.width;
  const cv::Size resized(key_width, std::max(1, static_cast<int>(std::lround(frames.height * factor))));
  if (map_camera && (map_camera->width() != resized.width || map_camera->height() != resized.height)) {
    throw InputError(args.sequence.string(),
                     fmt::format("frames are {}x{} ({}x{} at the map's width) but the map's camera images {}x{}: the "
                                 "sequence was not recorded with the map's camera",
                                 frames.width, frames.height, resized.width, resized.height, map_camera->width(),
                                 map_camera->height()));
  }
  if (camera->width() != key_width) camera = camera->Scaled(static_cast<double>(key_width) / camera->width());
  if (!args.camera.empty() && map_camera) {
    const double difference = CameraProjectionDifferencePx(*map_camera, *camera);
    if (!(difference <= kSameCameraPx) || camera->model_name() != map_camera->model_name()) {
      // Both calibrations at the frames' resolution, as the user wrote them.
      const double native = static_cast<double>(frames.width) / key_width;
      throw InputError(args.camera.string(),
                       fmt::format("differs from the map's camera ({} px apart at the map's {} px width): {} {} vs "
                                   "the map's {} {}; omit --camera to repeat with the map's camera",
                                   std::isfinite(difference) ? fmt::format("{:.1f}", difference) : "rays not imaged",
                                   key_width, camera->model_name(), DescribeCameraIntrinsics(*camera->Scaled(native)),
                                   map_camera->model_name(), DescribeCameraIntrinsics(*map_camera->Scaled(native))));
    }
  }
  if (camera->height() != resized.height) {
    throw InputError(args.sequence.string(), fmt::format("frames are {}x{} ({}x{} at the map's width) but the camera "
                                                         "images {}x{} at that width",
                                                         frames.width, frames.height, resized.width, resized.height,
                                                         camera->width(), camera->height()));
  }
  return camera;
}

void RunRepeat(const RepeatArguments& args) {
  MapForLocalizer loaded = LoadMapForLocalizer(args.map, args.options);
  const LocalizerOptions& options = loaded.options;
  const std::optional<std::string>& source = loaded.source_sequence;
  std::unique_ptr<Sequence> sequence = OpenInputSequence(args.sequence, args.bag);

  const int key_width = loaded.key_image_size.width;
  std::unique_ptr<CameraModel> camera = RepeatCamera(args, key_width, loaded.camera.get(), *sequence);

  if (args.every > 1 || args.offset > 0) {
    sequence = std::make_unique<SubsampledSequence>(std::move(sequence), std::max<size_t>(1, args.every), args.offset);
  }
  Localizer localizer(std::move(loaded.map), *camera, options);
  const Map& map = localizer.map();
  if (args.start_arc != kInvalidArcId) localizer.SetStartArc(args.start_arc);

  std::ofstream csv(args.output);
  if (!csv) throw InputError(args.output.string(), "cannot be written");
  csv << "frame,image,timestamp,state,arc,node_from,node_to,tracked,tracked_previous,tracked_current,tracked_next,"
         "resumed,rejected,dropped,drifted,redefined,sigma_p,sigma_p_from,sigma_p_to,position_on_arc,transition,"
         "steering,ms,position_via_from,position_via_to,position_via_pose,sigma_p_pose,pose_inliers,"
         "key_images_matched,confidence,evidence,belief_arc,lateral_m,lateral_sigma_m,heading_error_rad,along_m,"
         "to_next_m,curvature_ahead,frame_lateral_m,frame_lateral_sigma_m,heading_sigma_rad,along_sigma_m,"
         "heading_per_lateral\n";
  csv.flush();
  if (!args.overlay.empty()) std::filesystem::create_directories(args.overlay);

  std::vector<FrameResult> results;
  std::vector<RepeatRecord> records;
  {
    ProgressBar progress("repeat", sequence->size(), !args.no_progress);
    while (std::optional<Frame> frame = sequence->Next()) {
      if (frame->image.cols != camera->width()) {
        cv::Mat resized;
        ResizeToWidth(frame->image, camera->width(), &resized);
        frame->image = resized;
      }
      FrameResult r = localizer.ProcessFrame(*frame);
      csv << fmt::format("{},{},{:.6f},{},{},{},{},{},{},{},{},{},{},{},{},{},{:.3f},{:.3f},{:.3f},{:.4f},{},"
                         "{:.5f},{:.2f}",
                         frame->index, frame->name, frame->timestamp, LocalizerStateName(r.state), r.arc,
                         r.node_from, r.node_to, r.tracked, r.tracked_by_role[0], r.tracked_by_role[1],
                         r.tracked_by_role[2], r.resumed, r.rejected, r.dropped, r.drifted, r.redefined, r.sigma_p,
                         r.sigma_p_from, r.sigma_p_to, r.position_valid ? r.position_on_arc : 0.0, r.transition,
                         r.steering_valid ? r.steering : 0.0, 1000.0 * r.seconds)
          << fmt::format(",{},{},{},{:.3f},{},{},{:.5f},{},{}", OptionalNumber(r.position_via_from),
                         OptionalNumber(r.position_via_to), OptionalNumber(r.position_via_pose), r.sigma_p_pose,
                         r.pose_inliers, r.key_images_matched, r.confidence, r.evidence ? 1 : 0, r.belief_arc);
      if (r.path.valid) {
        csv << fmt::format(",{:.4f},{:.4f},{:.5f},{:.3f},{:.3f},{:.5f},{:.4f},{:.4f},{:.5f},{:.3f},{:.5f}\n",
                           r.path.lateral_m, r.path.lateral_sigma_m, r.path.heading_error_rad, r.path.along_m,
                           r.path.to_next_m, r.path.curvature_ahead, r.path.frame_lateral_m,
                           r.path.frame_lateral_sigma_m, r.path.heading_sigma_rad, r.path.along_sigma_m,
                           r.path.heading_per_lateral);
      } else {
        csv << ",,,,,,,,,,,\n";
      }
      csv.flush();
      if (!csv) throw InputError(args.output.string(), "write failed");
      if (!args.overlay.empty()) {
        const auto path = args.overlay / fmt::format("{:06d}.png", frame->index);
        if (!cv::imwrite(path.string(), DrawOverlay(frame->image, r))) {
          throw InputError(path.string(), "cannot be written");
        }
      }
      records.push_back({frame->source_index, r.state == LocalizerState::kTracking, r.arc});
      progress.Advance(1, r.state == LocalizerState::kTracking ? fmt::format("arc {}", r.arc)
                                                               : LocalizerStateName(r.state));
      r.marks.clear();
      r.marks.shrink_to_fit();
      results.push_back(std::move(r));
    }
  }
  if (!args.overlay.empty()) WriteTrackedPlot(results, args.overlay / "tracked.png");

  // Re-initialisations: every bootstrap after the first one (a loss, recovered in the same frame or later). Time:
  // all frames after the first (whose bootstrap extracts features of every key-image for retrieval), and the median
  // of the frames localized by tracking (without wide-baseline matching).
  int tracking = 0, bootstraps = 0, transitions = 0;
  double seconds = 0;
  std::vector<double> tracked_ms;
  for (size_t i = 0; i < results.size(); ++i) {
    const FrameResult& r = results[i];
    tracking += r.state == LocalizerState::kTracking;
    bootstraps += r.bootstrapped;
    transitions += r.transition != 0;
    if (i > 0) seconds += r.seconds;
    if (r.state == LocalizerState::kTracking && !r.bootstrapped) tracked_ms.push_back(1000.0 * r.seconds);
  }
  std::string timing;
  if (results.size() > 1) {
    timing = fmt::format("; {:.1f} frames/s after the first frame ({:.0f} ms)",
                         (results.size() - 1) / std::max(seconds, 1e-9), 1000.0 * results.front().seconds);
  }
  if (!tracked_ms.empty()) {
    std::nth_element(tracked_ms.begin(), tracked_ms.begin() + tracked_ms.size() / 2, tracked_ms.end());
    timing += fmt::format(", median {:.2f} ms per tracked frame", tracked_ms[tracked_ms.size() / 2]);
  }
  std::cout << fmt::format("repeat: {} frames, {} tracking, {} re-initialisations, {} transitions{}; peak memory "
                           "{:.0f} MB\n",
                           results.size(), tracking, std::max(0, bootstraps - 1), transitions, timing,
                           PeakResidentBytes() / 1e6);

  if (args.evaluate) {
    // Pseudo-repeat: key-images are frames of the teach sequence (map metadata), repeat frames of this one.
    const auto repeat_truth_file = sequence->ground_truth_file();
    if (!repeat_truth_file || repeat_truth_file->filename() != "poses.txt") {
      throw InputError(args.sequence.string(), "--evaluate needs KITTI ground-truth poses (poses.txt)");
    }
    if (!source) throw InputError(args.map.string(), "--evaluate: the map does not name its teach sequence");
    const auto key_truth_file = OpenSequence(*source)->ground_truth_file();
    if (!key_truth_file || key_truth_file->filename() != "poses.txt") {
      throw InputError(*source, "--evaluate needs KITTI ground-truth poses (poses.txt) of the teach sequence");
    }
    const std::vector<TimedPose> key_truth = ReadKittiPoses(*key_truth_file);
    const std::vector<TimedPose> repeat_truth = ReadKittiPoses(*repeat_truth_file);
    const TopologicalEvaluation evaluation = EvaluateTopological(map, key_truth, repeat_truth, records);
    std::cout << "topological ground truth: " << evaluation.Summary() << "\n";
    // Per frame, next to the run: which arc was true, which was reported (indices along the route).
    std::filesystem::path truth_path = args.output;
    truth_path.replace_extension(".truth.csv");
    std::ofstream truth(truth_path);
    truth << "frame,true_arc_index,tolerated_arc_index,estimated_arc_index,correct,lost,error,true_position_on_arc,"
             "tolerated_after_arc_index,true_lateral_m,true_heading_error_rad\n";
    // The metric path against the truth: the frame's true pose against the taught camera path around its arc.
    std::vector<double> lateral_errors, frame_lateral_errors, heading_errors;
    std::vector<double> true_lateral(results.size(), std::numeric_limits<double>::quiet_NaN());
    for (size_t i = 0; i < results.size(); ++i) {
      const FrameTruth& t = evaluation.per_frame[i];
      PathTruth path_truth;
      const FrameResult& r = results[i];
      if (r.state == LocalizerState::kTracking && records[i].source_index < repeat_truth.size()) {
        const MapArc* arc = map.FindArc(r.arc);
        const auto previous = map.ArcsTo(arc->from);
        const auto next = map.ArcsFrom(arc->to);
        const node_t first = previous.empty() ? arc->from : previous.front()->from;
        const node_t last = next.empty() ? arc->to : next.front()->to;
        const int64_t first_frame = map.FindNode(first)->source_frame, last_frame = map.FindNode(last)->source_frame;
        if (first_frame >= 0 && last_frame > first_frame) {
          path_truth = TruthAgainstTaughtPath(repeat_truth[records[i].source_index].world_from_cam, key_truth,
                                              static_cast<size_t>(first_frame), static_cast<size_t>(last_frame));
        }
      }
      if (path_truth.valid) true_lateral[i] = path_truth.lateral_m;
      if (path_truth.valid && r.path.valid) {
        lateral_errors.push_back(std::abs(r.path.lateral_m - path_truth.lateral_m));
        frame_lateral_errors.push_back(std::abs(r.path.frame_lateral_m - path_truth.lateral_m));
        heading_errors.push_back(std::abs(r.path.heading_error_rad - path_truth.heading_error_rad));
      }
      truth << fmt::format("{},{},{},{},{},{},{},{},{},{},{}\n", results[i].frame_index, t.true_arc_index,
                           t.tolerated_arc_index, t.estimated_arc_index, t.correct ? 1 : 0, t.lost ? 1 : 0, t.error,
                           OptionalNumber(t.true_position_on_arc), t.tolerated_after_arc_index,
                           path_truth.valid ? OptionalNumber(path_truth.lateral_m) : "",
                           path_truth.valid ? OptionalNumber(path_truth.heading_error_rad) : "");
    }
    if (!lateral_errors.empty()) {
      std::cout << fmt::format(
          "metric path against ground truth: {} frames, |lateral_m error| median {:.3f} m, 95th "
          "percentile {:.3f} m (each frame's own: {:.3f} / {:.3f} m); |heading error| median "
          "{:.2f} deg, 95th percentile {:.2f} deg\n",
          lateral_errors.size(), Quantile(lateral_errors, 0.5), Quantile(lateral_errors, 0.95),
          Quantile(frame_lateral_errors, 0.5), Quantile(frame_lateral_errors, 0.95),
          Quantile(heading_errors, 0.5) * 180 / M_PI, Quantile(heading_errors, 0.95) * 180 / M_PI);
    }
    if (!truth) throw InputError(truth_path.string(), "cannot be written");
    std::cout << "per-frame ground truth: " << truth_path.string() << "\n";
    if (!args.overlay.empty()) {
      WriteTruthPlot(results, evaluation, args.overlay / "arcs_vs_truth.png");
      WritePositionPlot(results, evaluation, args.overlay / "positions_vs_truth.png");
      WriteConfidencePlot(results, evaluation, options.belief.min_confidence, args.overlay / "confidence.png");
      if (!lateral_errors.empty()) WriteLateralPlot(results, true_lateral, args.overlay / "lateral_vs_truth.png");
    }
  }
}

}  // namespace

void RegisterRepeatCommand(CLI::App& app) {
  auto args = std::make_shared<RepeatArguments>();
  CLI::App* cmd = app.add_subcommand("repeat", "Localize a drive in a taught map, frame by frame, and steer");
  cmd->add_option("--map", args->map, "Map file written by `retrace teach`")->required();
  cmd->add_option("--sequence", args->sequence, "Image folder, video, KITTI or EuRoC layout, or ROS bag (*.bag)")
      ->required();
  AddBagOptions(cmd, &args->bag, /*with_camera_topic=*/false);
  cmd->add_option("--camera", args->camera, "Calibration file (default: the camera stored in the map)");
  cmd->add_option("--start-arc", args->start_arc, "Arc to bootstrap on (default: found by retrieval)");
  cmd->add_option("--output", args->output, "CSV file, one row per frame")->required();
  cmd->add_option("--overlay", args->overlay, "Folder for overlay images and a plot of tracked features");
  cmd->add_option("--every", args->every, "Use every k-th frame (e.g. 2)")->check(CLI::PositiveNumber);
  cmd->add_option("--offset", args->offset, "First frame used with --every (1 = odd frames)");
  cmd->add_flag("--evaluate", args->evaluate,
                "Compare the arcs with topological ground truth (KITTI poses of the teach and repeat sequences)");
  cmd->add_flag("--no-progress", args->no_progress, "Do not show the progress bar");
  cmd->add_option("--max-residual", args->options.max_residual, "R: largest tracking residual, grey levels")
      ->capture_default_str();
  cmd->add_flag("--affine-refine,!--no-affine-refine", args->options.affine_refinement,
                "Refine every tracked feature accepted under the paper's warp with an affine warp (less bias where the "
                "view is sheared, 2-3 m beside the taught path). On by default, with --placed-start-fine and "
                "--guided-matching 20 (README \"The three as the default\"); off: the paper's warp alone, about 14 % "
                "fewer instructions at 320 px");
  cmd->add_flag("--affine", args->options.affine_fallback,
                "Align tracks whose residual under the paper's warp is above R (within 1.5 R) again with an affine "
                "warp: more features 2-3 m beside the taught path, at a cost in speed and a few more frames on a "
                "wrong arc (README, validation matrix)");
  cmd->add_flag("--relocalization-affine", args->options.relocalization_affine_fallback,
                "Align the mapped features a relocalization locates with the affine fallback too (a start beside the "
                "taught path; README, \"Relocalization with the affine fallback\")");
  cmd->add_flag("--robust-relocalization", args->options.relocalization_robust_alignment,
                "After a loss, a mapped feature a relocalization cannot locate with the paper's warp is aligned again "
                "with the robust fallback (Tukey-weighted, accepted when 70 % of its window matches within R) and "
                "tracked with it; the place is still taken on the others, and a start does not use it. More frames "
                "tracked under another sun beside the path, but a pose on them may swerve a closed loop (README, "
                "\"Robust relocalization\")");
  cmd->add_flag(
      "--placed-start-fine,!--no-placed-start-fine", args->options.tracker.placed_features_start_fine,
      "Track the mapped features a relocalization or a prediction placed from a fine pyramid level in every "
      "frame, as they were placed (fewer tracks lost after a relocalization; alone, more frames tracked 2-3 m "
      "beside the taught path and a few more one arc behind: README, \"Features placed from a key-image\"; "
      "on by default, with --affine-refine)");
  cmd->add_flag("--verified-placement,!--no-verified-placement", args->options.place_by_verified_key_images,
                "When a relocalization verifies key-images but too few mapped features align through them (2.5 m "
                "beside the taught path, another sun), place the camera by resecting it from the key-images' matches "
                "and let the belief decide; on by default (README, \"Placed by the key-images a relocalization "
                "verified\")");
  cmd->add_flag(
      "--pose-point-uncertainty", args->options.pose_point_uncertainty,
      "Weigh each mapped point of the absolute pose by how well its arc's two key-images triangulated it "
      "(README, validation matrix: slightly better lateral_m at 0-2 m beside, a few more frames one arc off)");
  cmd->add_flag_callback(
      "--pose-point-uncertainty-covariance",
      [args]() {
        args->options.pose_point_uncertainty = true;
        args->options.pose.weigh_by_point_covariances = false;
      },
      "The points' uncertainty in the absolute pose's covariance only: the pose as with exact points, its sigma along "
      "the arc widened where far points near the key-images' epipole are seen from beside the path (docs/repeat.md, "
      "\"The points' uncertainty in the pose's covariance only\")");
  cmd->add_flag("--multi-view-points,!--no-multi-view-points", args->options.multi_view_points,
                "Triangulate each arc's points again from every key-image that sees them, the neighbouring arcs' "
                "outer key-images too; on by default since 2026-12-07, off: each arc's points as its two key-images "
                "made them (docs/repeat.md, \"Points from more than two key-images\")");
  cmd->add_option("--multi-view-max-residual", args->options.multi_view_max_residual_px,
                  "--multi-view-points: a point is kept as its arc made it when a key-image's residual exceeds this "
                  "(px at 320 px)")
      ->capture_default_str();
  cmd->add_option("--max-sigma-p", args->options.max_sigma_p_px, "sigma_p gate of current geometries, px at 320 px")
      ->capture_default_str();
  cmd->add_option("--steering-gain", args->options.steering_gain, "k of eq. (10)")->capture_default_str();
  cmd->add_option("--max-bad-frames", args->options.max_bad_frames,
                  "Frames in a row without usable tracks before they are given up and the frame relocalized")
      ->capture_default_str();
  cmd->add_option("--camera-height", args->options.path.camera_height,
                  "Height of the camera above the ground (m) for the metric offset from the taught path (default: "
                  "the one given to teach, stored in the map; without one the lateral_m columns stay empty)")
      ->check(CLI::Range(0.0, 100.0));
  cmd->add_option("--travel-window", args->options.path.travel_window,
                  "Arcs before and after the current one whose turns fit the vehicle's travel model (its camera's "
                  "mount yaw and distance ahead of the rear axle), from which each key-image's direction of travel, "
                  "heading_error_rad's reference, follows on straights (docs/path-tracking.md; 0: the arcs' "
                  "chords, for a robot that can move sideways)")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  cmd->add_option(
         "--lateral-window", args->options.lateral_filter.window,
         "Metres driven over which the recent frames' offsets from the taught path are combined into lateral_m "
         "(robustly, as a random walk; 0: each frame's own, which frame_lateral_m always holds)")
      ->check(CLI::Range(0.0, 1000.0))
      ->capture_default_str();
  cmd->add_option("--lateral-shared-correlation", args->options.lateral_filter.shared_correlation,
                  "Correlation in [0, 1) of the offset errors of two frames whose poses are in one arc's "
                  "reconstruction, when the recent frames' offsets are combined into lateral_m (0: independent)")
      ->check(CLI::Range(0.0, 0.999))
      ->capture_default_str();
  cmd->add_option("--min-confidence", args->options.belief.min_confidence,
                  "Belief confidence needed to report tracking (probability that the arc is right)")
      ->capture_default_str();
  cmd->add_option("--max-cached-key-images", args->options.max_cached_key_images,
                  "Key-images whose pyramids, references and key-points stay in memory (least recently used "
                  "released first; bounds memory on long drives)")
      ->capture_default_str();
  cmd->add_option("--retrieval-shortlist", args->options.retrieval_shortlist,
                  "Verification budget when localizing without a start arc: at most this many key-images verified "
                  "per frame, the most similar in appearance first, stopping at the first confident one (0: all)")
      ->capture_default_str();
  cmd->add_option("--start-retrieval-shortlist", args->options.start_retrieval_shortlist,
                  "The same budget for the frames before the first localization (a robot at its start can spend "
                  "more time on a frame than a lost one moving along; 0: all)")
      ->capture_default_str();
  cmd->add_flag("!--sift", args->options.binary_relocalization,
                "Relocalize with SIFT from three detectors extracted at run time (as before issue 16), not with the "
                "binary key-points the map stores");
  cmd->add_flag("!--no-visual-words", args->options.visual_word_retrieval,
                "Rank the whole map's key-images for relocalization by their appearance thumbnails alone, not fused "
                "with their visual words");
  cmd->add_flag("!--no-absolute-pose", args->options.place_by_absolute_pose,
                "Place the camera on the arc by the current geometries alone (the paper), not by its absolute pose in "
                "the arc's reconstruction");
  cmd->add_option("--start-alternative-starts", args->options.start_alternative_starts,
                  "Before the first localization, a mapped feature that does not align from the median displacement "
                  "of the matches around it is aligned from each of the nearest matches in turn, at most this many, "
                  "and kept only as an inlier of the verified pose (0: the median alone; README \"Mapped features "
                  "located from the nearest matches\")")
      ->check(CLI::Range(0, 100))
      ->capture_default_str();
  cmd->add_option("--alternative-starts", args->options.bootstrap_alternative_starts,
                  "The same after a loss (more frames tracked beside the path, a few more one arc off)")
      ->check(CLI::Range(0, 100))
      ->capture_default_str();
  cmd->add_option("--guided-matching", args->options.guided_matching_min_inliers,
                  "Near a loss or the start, match a key-image again along the epipolar planes of a relative pose "
                  "with at least this many inliers, to verify it (0: off; README \"Guided matching near a loss\")")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  cmd->add_flag("!--keep-references", args->options.redefine_references,
                "Do not redefine feature references at topological transitions (Segvic 2009 5.2.2 does)");
  cmd->callback([args]() {
    std::string error;
    if (!args->options.Check(&error)) throw InputError("repeat options", error);
    RunRepeat(*args);
  });
}

}  // namespace retrace
