#include "retrace/sim/recording.h"

#include <chrono>
#include <fstream>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "retrace/camera/camera_io.h"
#include "retrace/camera/perspective_camera.h"
#include "retrace/dataset/kitti_writer.h"
#include "retrace/image/image_utils.h"
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

// What a recorded sequence holds besides its frames: the scenario, the camera file and (perspective cameras) the
// KITTI calibration.
void WriteSequenceHeader(const Simulator& sim, const std::filesystem::path& out_dir, KittiSequenceWriter* writer) {
  WriteText(out_dir / "scenario.yaml", ScenarioToYaml(sim.scenario()));
  WriteCameraFile(sim.camera(), out_dir / "camera.yaml");
  if (const auto* perspective = dynamic_cast<const PerspectiveCamera*>(&sim.camera())) {
    Matrix34d p0 = Matrix34d::Zero();
    p0.leftCols<3>() = perspective->K();
    writer->WriteCalibration(p0);
  }
}

}  // namespace

RecordedDrive RecordDrive(const Scenario& scenario) {
  Simulator simulator(scenario);
  RecordedDrive drive;
  drive.camera = simulator.camera().Clone();
  SimFrame sim_frame;
  while (simulator.NextFrame(&sim_frame)) {
    Frame frame;
    frame.index = frame.source_index = drive.frames.size();
    frame.name = fmt::format("{:06d}.png", frame.index);
    frame.timestamp = sim_frame.timestamp;
    frame.image = sim_frame.image;
    drive.frames.push_back(std::move(frame));
    drive.truth.push_back({sim_frame.timestamp, sim_frame.world_from_cam});
  }
  return drive;
}

RecordSummary RecordPoses(Simulator* sim, const std::vector<TimedPose>& poses, const std::filesystem::path& out_dir,
                          const RecordOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  KittiSequenceWriter writer(out_dir);
  WriteSequenceHeader(*sim, out_dir, &writer);
  RecordSummary summary;
  summary.route_length_m = sim->route().length();
  ProgressBar progress("render", poses.size(), options.progress);
  for (size_t i = 0; i < poses.size(); ++i) {
    const cv::Mat image = sim->RenderAt(poses[i].world_from_cam, poses[i].timestamp, /*noise_seed=*/i + 1);
    writer.WriteFrame(image, poses[i].timestamp, poses[i].world_from_cam);
    if (i > 0) {
      summary.driven_m += (poses[i].world_from_cam.translation - poses[i - 1].world_from_cam.translation).norm();
    }
    ++summary.frames;
    progress.Advance(1);
  }
  progress.Finish();
  summary.frames_requested = static_cast<int>(poses.size());
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

RecordSummary RecordSequence(Simulator* sim, const std::filesystem::path& out_dir, const RecordOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  KittiSequenceWriter writer(out_dir);
  WriteSequenceHeader(*sim, out_dir, &writer);

  RecordSummary summary;
  summary.route_length_m = sim->route().length();
  ProgressBar progress("render", static_cast<size_t>(sim->ExpectedFrames()), options.progress);
  std::vector<cv::Mat> thumbs;
  std::vector<std::string> labels;
  SimFrame frame;
  while (sim->NextFrame(&frame)) {
    writer.WriteFrame(frame.image, frame.timestamp, frame.world_from_cam);
    if (!options.contact_sheet.empty() && summary.frames % std::max(1, options.contact_sheet_every) == 0) {
      thumbs.push_back(frame.image);
      labels.push_back(fmt::format("#{} t={:.1f}s", summary.frames, frame.timestamp));
    }
    summary.driven_m = frame.progress;
    ++summary.frames;
    progress.Advance(1);
  }
  progress.Finish();
  summary.frames_requested = sim->scenario().num_frames;
  summary.stopped_at_route_end = summary.frames_requested > 0 && summary.frames < summary.frames_requested;
  if (!options.contact_sheet.empty() && !thumbs.empty()) {
    const cv::Mat sheet = MakeContactSheet(thumbs, labels, options.contact_sheet_columns, 320);
    if (!cv::imwrite(options.contact_sheet.string(), sheet)) {
      throw InputError(options.contact_sheet.string(), "cannot write the contact sheet");
    }
  }
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace retrace
