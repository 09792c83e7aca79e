// `retrace perturb`: a perturbed copy of a sequence in the KITTI layout, for pseudo-repeat evaluation on single-pass
// data (design §9). Photometric changes, noise, blur and a moving occluder come from retrace::PerturbImage; frames can
// be subsampled (--every/--offset: "teach on even, repeat on odd") and dropped (--drop-every). The ground-truth poses
// of the kept frames are written alongside, so ground truth stays aligned; source_frames.txt gives the original index
// of every output frame.

#include <filesystem>
#include <fstream>
#include <iostream>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "retrace/camera/camera_io.h"
#include "retrace/dataset/ground_truth.h"
#include "retrace/dataset/kitti_writer.h"
#include "retrace/dataset/sequence.h"
#include "retrace/exe/commands.h"
#include "retrace/image/perturbation.h"
#include "retrace/util/error.h"
#include "retrace/util/progress.h"

namespace retrace {
namespace {
namespace fs = std::filesystem;

struct PerturbArgs {
  std::string sequence;
  std::string out;
  PerturbationOptions options;
  std::string occluder_frames;
  bool occluder_flat = false;
  size_t every = 1;
  size_t offset = 0;
  size_t drop_every = 0;
  double frame_rate = 1.0;
};

// "A:B" -> [A, B] inclusive.
void ParseFrameRange(const std::string& text, PerturbationOptions* options) {
  const size_t colon = text.find(':');
  try {
    size_t used_a = 0;
    size_t used_b = 0;
    if (colon == std::string::npos) throw std::invalid_argument("");
    const std::string a = text.substr(0, colon);
    const std::string b = text.substr(colon + 1);
    options->occluder_first_frame = std::stoll(a, &used_a);
    options->occluder_last_frame = std::stoll(b, &used_b);
    if (used_a != a.size() || used_b != b.size()) throw std::invalid_argument("");
  } catch (const std::exception&) {
    throw InputError("--occluder-frames", "'" + text + "' is not a frame range FIRST:LAST");
  }
  if (options->occluder_last_frame < options->occluder_first_frame) {
    throw InputError("--occluder-frames", "'" + text + "': LAST is before FIRST");
  }
}

void RunPerturb(PerturbArgs args) {
  if (!args.occluder_frames.empty()) ParseFrameRange(args.occluder_frames, &args.options);
  if (args.options.occluder_fraction > 0 && args.occluder_frames.empty()) {
    throw InputError("--occluder-fraction", "needs --occluder-frames FIRST:LAST");
  }
  args.options.occluder_textured = !args.occluder_flat;
  std::string error;
  if (!args.options.Check(&error)) throw InputError("", "invalid perturbation: " + error);

  SequenceOptions sequence_options;
  sequence_options.frame_rate = args.frame_rate;
  std::unique_ptr<Sequence> sequence = OpenSequence(args.sequence, sequence_options);

  const fs::path out(args.out);
  std::error_code ec;
  if (fs::exists(out, ec) && !(fs::is_directory(out, ec) && fs::is_empty(out, ec))) {
    throw InputError(out.string(), "exists and is not an empty folder (remove it or choose another --out)");
  }

  // Ground truth that is one camera pose per listed frame (KITTI poses.txt) is carried over; EuRoC body poses are not
  // camera poses and are left out.
  std::vector<TimedPose> poses;
  if (const std::optional<fs::path> gt = sequence->ground_truth_file()) {
    if (sequence->layout() == "euroc") {
      spdlog::warn("{}: EuRoC ground truth holds body poses at other times; not copied", gt->string());
    } else {
      poses = ReadKittiPoses(*gt);
      if (poses.size() != sequence->size()) {
        throw InputError(gt->string(), fmt::format("{} poses for {} frames", poses.size(), sequence->size()));
      }
    }
  }

  KittiSequenceWriter writer(out);
  if (const std::optional<fs::path> calibration = sequence->calibration_file()) {
    const fs::path target = out / calibration->filename();
    fs::copy_file(*calibration, target, fs::copy_options::overwrite_existing, ec);
    CheckInput(!ec, target.string(), "cannot copy the calibration file: " + ec.message());
    // The frames are written to image_0, whose camera in a KITTI calib.txt is P0: frames of another of its cameras
    // (image_2, ...) take theirs along as camera.yaml, which a KITTI folder's reader prefers.
    const std::string camera = sequence->calibration_camera();
    if (!camera.empty() && camera != "P0" && calibration->filename() != "camera.yaml") {
      WriteCameraFile(*ReadCameraFile(*calibration, sequence->image_size(), camera), out / "camera.yaml");
    }
  }
  const fs::path source_frames_path = out / "source_frames.txt";
  std::ofstream source_frames(source_frames_path);
  CheckInput(source_frames.is_open(), source_frames_path.string(), "cannot open the file for writing");

  SubsampledSequence selected(std::move(sequence), args.every, args.offset);
  ProgressBar progress("perturb", selected.size());
  size_t dropped = 0;
  while (std::optional<Frame> frame = selected.Next()) {
    progress.Advance();
    // --drop-every N drops the N-th, 2N-th, ... selected frame.
    if (args.drop_every > 0 && (frame->index + 1) % args.drop_every == 0) {
      ++dropped;
      continue;
    }
    // Perturbations are indexed by the ORIGINAL frame index, so --occluder-frames refers to the source sequence.
    const cv::Mat image = PerturbImage(frame->image, static_cast<int64_t>(frame->source_index), args.options);
    if (poses.empty()) {
      writer.WriteFrame(image, frame->timestamp);
    } else {
      writer.WriteFrame(image, frame->timestamp, poses[frame->source_index].world_from_cam);
    }
    source_frames << frame->source_index << '\n';
    source_frames.flush();
    CheckInput(static_cast<bool>(source_frames), source_frames_path.string(), "cannot write the file");
  }
  progress.Finish();

  std::cout << fmt::format("wrote {} frames to {} ({} dropped, {} unreadable in the source){}\n",
                           writer.frames_written(), out.string(), dropped, selected.skipped().size(),
                           poses.empty() ? "" : " with ground-truth poses");
}

}  // namespace

void RegisterPerturbCommand(CLI::App& app) {
  auto args = std::make_shared<PerturbArgs>();
  CLI::App* cmd = app.add_subcommand(
      "perturb", "Write a perturbed copy of a sequence (KITTI layout) for pseudo-repeat evaluation");
  cmd->add_option("--sequence", args->sequence, "Input sequence (folder, video, KITTI or EuRoC)")->required();
  cmd->add_option("--out", args->out, "Output folder (KITTI layout; must not exist or be empty)")->required();
  PerturbationOptions& o = args->options;
  cmd->add_option("--brightness", o.brightness, "Gain a: v' = a v^gamma (1 = unchanged)")->capture_default_str();
  cmd->add_option("--gamma", o.gamma, "Gamma exponent (1 = unchanged)")->capture_default_str();
  cmd->add_option("--contrast", o.contrast, "Contrast factor about mid-grey (1 = unchanged)")->capture_default_str();
  cmd->add_option("--noise", o.noise_sigma, "Gaussian noise standard deviation in grey levels")->capture_default_str();
  cmd->add_option("--blur", o.blur_sigma, "Gaussian blur standard deviation in pixels")->capture_default_str();
  cmd->add_option("--occluder-fraction", o.occluder_fraction, "Image area fraction covered by a moving occluder")->capture_default_str();
  cmd->add_option("--occluder-frames", args->occluder_frames,
                  "FIRST:LAST original frame indices (inclusive) during which the occluder crosses the image");
  cmd->add_flag("--occluder-flat", args->occluder_flat, "Flat black occluder instead of a textured one");
  cmd->add_option("--every", args->every, "Keep every K-th frame of the source (with --offset)")->capture_default_str()
      ->check(CLI::PositiveNumber);
  cmd->add_option("--offset", args->offset, "First source frame kept by --every")->capture_default_str();
  cmd->add_option("--drop-every", args->drop_every, "Drop every N-th kept frame (N-th, 2N-th, ...); 0 = none")->capture_default_str();
  cmd->add_option("--seed", o.seed, "Seed of noise, occluder texture and position")->capture_default_str();
  cmd->add_option("--fps", args->frame_rate, "Frame rate assumed for an image folder without times.txt")->capture_default_str()
      ->check(CLI::PositiveNumber);
  cmd->callback([args]() { RunPerturb(*args); });
}

}  // namespace retrace
