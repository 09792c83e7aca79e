// `retrace calibrate`: intrinsic calibration from a folder of chessboard images; writes a camera file.

#include <iostream>
#include <regex>

#include <fmt/format.h>

#include "retrace/camera/calibration.h"
#include "retrace/camera/camera_io.h"
#include "retrace/exe/commands.h"
#include "retrace/util/error.h"

namespace retrace {
namespace {

struct CalibrateArguments {
  std::string images;
  std::string board = "9x6";
  double square = 1.0;
  std::string out;
  std::string model = "perspective";
  bool fix_aspect_ratio = false;
  bool no_k3 = false;
  int min_images = 4;
};

void RunCalibrate(const CalibrateArguments& args) {
  ChessboardCalibrationOptions options;
  std::smatch match;
  if (!std::regex_match(args.board, match, std::regex(R"((\d{1,3})x(\d{1,3}))"))) {
    throw InputError("", "invalid --board '" + args.board + "': expected COLSxROWS inner corners, e.g. 9x6");
  }
  options.board_size = cv::Size(std::stoi(match[1]), std::stoi(match[2]));
  if (options.board_size.width < 2 || options.board_size.height < 2) {
    throw InputError("", "invalid --board '" + args.board + "': at least 2x2 inner corners");
  }
  if (!(args.square > 0.0)) throw InputError("", fmt::format("invalid --square {}: must be positive", args.square));
  if (args.model == "perspective") {
    options.model = CalibrationModel::kPerspective;
  } else if (args.model == "unified") {
    options.model = CalibrationModel::kUnified;
  } else {
    throw InputError("", "invalid --model '" + args.model + "': expected perspective or unified");
  }
  if (args.min_images < 3) throw InputError("", "invalid --min-images: at least 3");
  options.square_size = args.square;
  options.fix_aspect_ratio = args.fix_aspect_ratio;
  options.estimate_k3 = !args.no_k3;
  options.min_images = args.min_images;

  const std::vector<std::filesystem::path> files = ListImageFiles(args.images);  // fails early on a bad folder
  std::cout << fmt::format("calibrating the {} model from {} images in {} ({} board, square {})\n", args.model,
                           files.size(), args.images, args.board, args.square);
  const ChessboardCalibrationResult result = CalibrateChessboardFolder(args.images, options);
  for (const CalibrationImage& image : result.images) {
    if (image.used) {
      std::cout << fmt::format("  {:<32} used     rms {:.3f} px\n", image.name, image.rms_error_px);
    } else {
      std::cout << fmt::format("  {:<32} skipped  {}\n", image.name, image.reason);
    }
  }
  std::cout << fmt::format("RMS reprojection error: {:.4f} px over {} of {} images\n", result.rms_error_px,
                           result.NumUsed(), result.images.size());
  std::cout << DescribeCamera(*result.camera);
  WriteCameraFile(*result.camera, args.out);
  ReadCameraFile(args.out);  // the file must read back
  std::cout << "wrote " << args.out << "\n";
}

}  // namespace

void RegisterCalibrateCommand(CLI::App& app) {
  auto args = std::make_shared<CalibrateArguments>();
  CLI::App* cmd = app.add_subcommand("calibrate", "Calibrate a camera from chessboard images");
  cmd->add_option("--images", args->images, "Folder of chessboard images")->required();
  cmd->add_option("--board", args->board, "Inner corners of the board, COLSxROWS")->capture_default_str();
  cmd->add_option("--square", args->square, "Side of one square (unit of the board poses)")->capture_default_str();
  cmd->add_option("--out", args->out, "Camera file to write (YAML, ROS camera_info layout)")->required();
  cmd->add_option("--model", args->model, "Camera model: perspective or unified")->capture_default_str();
  cmd->add_flag("--fix-aspect-ratio", args->fix_aspect_ratio, "Perspective: force fx = fy");
  cmd->add_flag("--no-k3", args->no_k3, "Perspective: do not estimate the radial coefficient k3");
  cmd->add_option("--min-images", args->min_images, "Fewest images with a detected board")->capture_default_str();
  cmd->callback([args]() { RunCalibrate(*args); });
}

}  // namespace retrace
