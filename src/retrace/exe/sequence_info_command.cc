// `retrace sequence-info PATH`: what OpenSequence sees in a folder, video, KITTI or EuRoC layout — layout, frame
// count, image size, time span, calibration and ground-truth files, trajectory length, unreadable frames.

#include <filesystem>
#include <iostream>
#include <limits>

#include <fmt/format.h>

#include "retrace/dataset/ground_truth.h"
#include "retrace/dataset/sequence.h"
#include "retrace/exe/commands.h"
#include "retrace/exe/sequence_input.h"

namespace retrace {
namespace {

struct SequenceInfoArgs {
  std::string path;
  double frame_rate = 1.0;
  BagInput bag;
};

void RunSequenceInfo(const SequenceInfoArgs& args) {
  SequenceOptions options;
  options.frame_rate = args.frame_rate;
  std::unique_ptr<Sequence> sequence = std::filesystem::path(args.path).extension() == ".bag" || !args.bag.topic.empty() ||
                                                   !args.bag.camera_topic.empty()
                                           ? OpenInputSequence(args.path, args.bag)
                                           : OpenSequence(args.path, options);

  // Read every frame: the only honest way to know which ones are readable.
  size_t readable = 0;
  double first_time = std::numeric_limits<double>::quiet_NaN();
  double last_time = first_time;
  cv::Size size;
  while (std::optional<Frame> frame = sequence->Next()) {
    if (readable == 0) {
      first_time = frame->timestamp;
      size = frame->image.size();
    }
    last_time = frame->timestamp;
    ++readable;
  }

  std::cout << fmt::format("path:          {}\n", sequence->path().string());
  std::cout << fmt::format("layout:        {}\n", sequence->layout());
  const std::string listed = sequence->size() > 0 ? fmt::format("{} listed, ", sequence->size()) : "";
  std::cout << fmt::format("frames:        {}{} readable\n", listed, readable);
  if (readable > 0) {
    std::cout << fmt::format("image size:    {}x{}\n", size.width, size.height);
    std::cout << fmt::format("time span:     {:.6f} .. {:.6f} s ({:.3f} s)\n", first_time, last_time,
                             last_time - first_time);
  }
  const std::optional<std::filesystem::path> calibration = sequence->calibration_file();
  if (sequence->layout() == "rosbag") {
    const std::unique_ptr<CameraModel> camera = SequenceCamera(*sequence);
    std::cout << fmt::format("calibration:   {}\n", camera ? "CameraInfo, " + camera->model_name() : "none");
  } else {
    const std::string camera = sequence->calibration_camera();
    std::cout << fmt::format("calibration:   {}{}\n", calibration ? calibration->string() : "none",
                             calibration && !camera.empty() ? " (" + camera + ")" : "");
  }
  const std::optional<std::filesystem::path> ground_truth = sequence->ground_truth_file();
  if (!ground_truth) {
    std::cout << "ground truth:  none\n";
  } else if (sequence->layout() == "euroc") {
    const std::vector<TimedPose> poses = ReadEurocPoses(*ground_truth);
    std::cout << fmt::format("ground truth:  {} ({} body poses, {:.3f} .. {:.3f} s)\n", ground_truth->string(),
                             poses.size(), poses.front().timestamp, poses.back().timestamp);
    std::cout << fmt::format("trajectory:    {:.2f} m (body)\n", TrajectoryLength(poses));
  } else {
    const std::vector<TimedPose> poses = ReadKittiPoses(*ground_truth);
    std::cout << fmt::format("ground truth:  {} ({} camera poses)\n", ground_truth->string(), poses.size());
    std::cout << fmt::format("trajectory:    {:.2f} m\n", TrajectoryLength(poses));
    if (sequence->size() > 0 && poses.size() != sequence->size()) {
      std::cout << fmt::format("warning:       {} poses for {} frames\n", poses.size(), sequence->size());
    }
  }
  const std::vector<std::string>& skipped = sequence->skipped();
  std::cout << fmt::format("unreadable:    {}\n", skipped.empty() ? "none" : fmt::format("{}", skipped.size()));
  for (const std::string& name : skipped) std::cout << "  " << name << "\n";
}

}  // namespace

void RegisterSequenceInfoCommand(CLI::App& app) {
  auto args = std::make_shared<SequenceInfoArgs>();
  CLI::App* cmd = app.add_subcommand(
      "sequence-info", "Describe an image sequence (folder, video, KITTI or EuRoC layout) and its ground truth");
  cmd->add_option("path", args->path, "Sequence folder, video file or ROS bag (*.bag)")->required();
  AddBagOptions(cmd, &args->bag, /*with_camera_topic=*/true);
  cmd->add_option("--fps", args->frame_rate, "Frame rate assumed for an image folder without times.txt")
      ->check(CLI::PositiveNumber);
  cmd->callback([args]() { RunSequenceInfo(*args); });
}

}  // namespace retrace
