#include "retrace/sim/recording.h"

#include <chrono>
#include <fstream>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "retrace/camera/perspective_camera.h"
#include "retrace/sim/scenario_io.h"
#include "retrace/util/error.h"
#include "retrace/util/progress.h"

namespace retrace {
namespace {

void WriteText(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
  if (!out) throw InputError(path.string(), "cannot write the file");
}

}  // namespace

std::string KittiPoseLine(const Rigid3d& world_from_cam) {
  const Matrix34d m = world_from_cam.ToMatrix();
  std::string line;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) line += fmt::format("{}{:.9e}", line.empty() ? "" : " ", m(r, c));
  }
  return line + "\n";
}

std::string KittiCalibText(const CameraModel& camera) {
  std::string text;
  const auto* p = dynamic_cast<const PerspectiveCamera*>(&camera);
  if (!p) return text;
  const Matrix3d k = p->K();
  for (int cam = 0; cam < 4; ++cam) {
    text += fmt::format("P{}:", cam);
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) text += fmt::format(" {:.12e}", c < 3 ? k(r, c) : 0.0);
    }
    text += "\n";
  }
  return text;
}

std::string CameraYaml(const CameraModel& camera) {
  std::string y = fmt::format("model: {}\nwidth: {}\nheight: {}\n", camera.model_name(), camera.width(),
                              camera.height());
  if (const auto* p = dynamic_cast<const PerspectiveCamera*>(&camera)) {
    const LensDistortion& d = p->distortion();
    y += fmt::format("fx: {:.12g}\nfy: {:.12g}\ncx: {:.12g}\ncy: {:.12g}\nskew: {:.12g}\n", p->fx(), p->fy(), p->cx(),
                     p->cy(), p->skew());
    y += fmt::format("distortion: {{k1: {:.12g}, k2: {:.12g}, p1: {:.12g}, p2: {:.12g}, k3: {:.12g}}}\n", d.k1, d.k2,
                     d.p1, d.p2, d.k3);
  }
  return y;
}

cv::Mat SimContactSheet(const std::vector<cv::Mat>& images, const std::vector<std::string>& labels, int columns,
                        int thumb_width) {
  if (images.empty()) return cv::Mat();
  const double scale = static_cast<double>(thumb_width) / images[0].cols;
  const int thumb_height = static_cast<int>(std::round(images[0].rows * scale));
  const int rows = (static_cast<int>(images.size()) + columns - 1) / columns;
  const int gap = 4;
  cv::Mat sheet(rows * (thumb_height + gap) + gap, columns * (thumb_width + gap) + gap, CV_8UC3,
                cv::Scalar(40, 40, 40));
  for (size_t i = 0; i < images.size(); ++i) {
    cv::Mat thumb, bgr;
    cv::resize(images[i], thumb, cv::Size(thumb_width, thumb_height), 0, 0, cv::INTER_AREA);
    if (thumb.channels() == 1) {
      cv::cvtColor(thumb, bgr, cv::COLOR_GRAY2BGR);
    } else {
      bgr = thumb;
    }
    const int x = gap + static_cast<int>(i % columns) * (thumb_width + gap);
    const int y = gap + static_cast<int>(i / columns) * (thumb_height + gap);
    bgr.copyTo(sheet(cv::Rect(x, y, thumb_width, thumb_height)));
    if (i < labels.size()) {
      cv::putText(sheet, labels[i], cv::Point(x + 4, y + 14), cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0), 3);
      cv::putText(sheet, labels[i], cv::Point(x + 4, y + 14), cv::FONT_HERSHEY_SIMPLEX, 0.4,
                  cv::Scalar(255, 255, 255), 1);
    }
  }
  return sheet;
}

RecordSummary RecordSequence(Simulator* sim, const std::filesystem::path& out_dir, const RecordOptions& options) {
  namespace fs = std::filesystem;
  const auto start = std::chrono::steady_clock::now();
  std::error_code error;
  fs::create_directories(out_dir / "image_0", error);
  if (error) throw InputError(out_dir.string(), "cannot create the output folder: " + error.message());
  WriteText(out_dir / "scenario.yaml", ScenarioToYaml(sim->scenario()));
  WriteText(out_dir / "camera.yaml", CameraYaml(sim->camera()));
  const std::string calib = KittiCalibText(sim->camera());
  if (!calib.empty()) WriteText(out_dir / "calib.txt", calib);
  std::ofstream times(out_dir / "times.txt"), poses(out_dir / "poses.txt");
  if (!times || !poses) throw InputError(out_dir.string(), "cannot write times.txt / poses.txt");

  RecordSummary summary;
  summary.route_length_m = sim->route().length();
  ProgressBar progress("render", static_cast<size_t>(sim->ExpectedFrames()), options.progress);
  std::vector<cv::Mat> thumbs;
  std::vector<std::string> labels;
  SimFrame frame;
  while (sim->NextFrame(&frame)) {
    const fs::path image_path = out_dir / "image_0" / fmt::format("{:06d}.png", summary.frames);
    if (!cv::imwrite(image_path.string(), frame.image)) throw InputError(image_path.string(), "cannot write image");
    times << fmt::format("{:.6e}\n", frame.timestamp);
    poses << KittiPoseLine(frame.world_from_cam);
    if (!options.contact_sheet.empty() && summary.frames % std::max(1, options.contact_sheet_every) == 0) {
      thumbs.push_back(frame.image);
      labels.push_back(fmt::format("#{} t={:.1f}s", summary.frames, frame.timestamp));
    }
    summary.driven_m = frame.progress;
    ++summary.frames;
    progress.Advance(1);
  }
  progress.Finish();
  if (!times || !poses) throw InputError(out_dir.string(), "cannot write times.txt / poses.txt");
  if (!options.contact_sheet.empty() && !thumbs.empty()) {
    const cv::Mat sheet = SimContactSheet(thumbs, labels, options.contact_sheet_columns, 320);
    if (!cv::imwrite(options.contact_sheet.string(), sheet)) {
      throw InputError(options.contact_sheet.string(), "cannot write the contact sheet");
    }
  }
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace retrace
