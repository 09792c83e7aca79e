// `retrace camera-info`: reads a camera file and prints the model, its parameters, the field of view and how well
// projection and unprojection (distortion and its inverse) agree over the image.

#include <cmath>
#include <iostream>
#include <optional>
#include <regex>

#include <fmt/format.h>

#include "retrace/camera/camera_io.h"
#include "retrace/exe/commands.h"
#include "retrace/util/error.h"
#include "retrace/util/types.h"

namespace retrace {
namespace {

struct CameraInfoArguments {
  std::string camera;
  std::string image_size;
};

// Angle swept by the rays along a line of pixels from `from` to `to` (sums the steps, so 360 degrees for a
// panorama); pixels without a ray are skipped.
double SweptAngleDeg(const CameraModel& camera, const Vector2d& from, const Vector2d& to) {
  constexpr int kSteps = 2000;
  double total = 0.0;
  std::optional<Vector3d> previous;
  for (int i = 0; i <= kSteps; ++i) {
    Vector3d bearing;
    if (!camera.Unproject(from + (to - from) * i / kSteps, &bearing)) {
      previous.reset();
      continue;
    }
    if (previous) total += AngleBetweenDeg(*previous, bearing);
    previous = bearing;
  }
  return total;
}

void RunCameraInfo(const CameraInfoArguments& args) {
  std::optional<cv::Size> size;
  if (!args.image_size.empty()) {
    std::smatch match;
    if (!std::regex_match(args.image_size, match, std::regex(R"((\d{1,6})x(\d{1,6}))"))) {
      throw InputError("", "invalid --image-size '" + args.image_size + "': expected WIDTHxHEIGHT, e.g. 640x480");
    }
    size = cv::Size(std::stoi(match[1]), std::stoi(match[2]));
  }
  const auto camera = ReadCameraFile(args.camera, size);
  std::cout << "file: " << args.camera << "\n" << DescribeCamera(*camera);

  // Field of view over the image's outer pixel edges.
  const double w = camera->width(), h = camera->height();
  const double horizontal = SweptAngleDeg(*camera, Vector2d(-0.5, 0.5 * h - 0.5), Vector2d(w - 0.5, 0.5 * h - 0.5));
  const double vertical = SweptAngleDeg(*camera, Vector2d(0.5 * w - 0.5, -0.5), Vector2d(0.5 * w - 0.5, h - 0.5));
  const double diagonal = SweptAngleDeg(*camera, Vector2d(-0.5, -0.5), Vector2d(w - 0.5, h - 0.5));
  std::cout << fmt::format("field of view: horizontal {:.2f} deg, vertical {:.2f} deg, diagonal {:.2f} deg\n",
                           horizontal, vertical, diagonal);

  // Widest ray from the optical axis (+z) over the image border; above 90 degrees the camera sees behind itself.
  double max_from_axis = 0.0;
  for (int i = 0; i <= 4000; ++i) {
    const double s = i / 4000.0;
    for (const Vector2d& pixel : {Vector2d(-0.5 + s * w, -0.5), Vector2d(-0.5 + s * w, h - 0.5),
                                  Vector2d(-0.5, -0.5 + s * h), Vector2d(w - 0.5, -0.5 + s * h)}) {
      Vector3d bearing;
      if (camera->Unproject(pixel, &bearing)) {
        max_from_axis = std::max(max_from_axis, AngleBetweenDeg(bearing, Vector3d::UnitZ()));
      }
    }
  }
  std::cout << fmt::format("widest ray at the image border: {:.2f} deg from the optical axis\n", max_from_axis);

  // Round trip pixel -> ray -> pixel over a grid covering the whole image.
  const int step = std::max(1, static_cast<int>(std::sqrt(w * h / 200000.0)));
  double max_error = 0.0, sum_error = 0.0;
  long samples = 0, without_ray = 0;
  Vector2d worst(0, 0);
  for (int y = 0; y < camera->height(); y += step) {
    for (int x = 0; x < camera->width(); x += step) {
      const Vector2d pixel(x, y);
      Vector3d bearing;
      Vector2d back;
      ++samples;
      if (!camera->Unproject(pixel, &bearing) || !camera->Project(bearing, &back)) {
        ++without_ray;
        continue;
      }
      const double error = (back - pixel).norm();
      sum_error += error;
      if (error > max_error) {
        max_error = error;
        worst = pixel;
      }
    }
  }
  const long with_ray = samples - without_ray;
  std::cout << fmt::format("round-trip error (pixel -> ray -> pixel, every {} px): max {:.3g} px at ({:.0f}, "
                           "{:.0f}), mean {:.3g} px\n",
                           step, max_error, worst.x(), worst.y(), with_ray > 0 ? sum_error / with_ray : 0.0);
  if (without_ray > 0) {
    std::cout << fmt::format("pixels without a ray (outside the model's valid area): {} of {} ({:.1f}%)\n",
                             without_ray, samples, 100.0 * without_ray / samples);
  }
}

}  // namespace

void RegisterCameraInfoCommand(CLI::App& app) {
  auto args = std::make_shared<CameraInfoArguments>();
  CLI::App* cmd = app.add_subcommand("camera-info", "Print a camera file's model, parameters and field of view");
  cmd->add_option("--camera", args->camera, "Camera calibration file (ROS, OpenCV, KITTI, EuRoC, retrace)")
      ->required();
  cmd->add_option("--image-size", args->image_size, "Image size WIDTHxHEIGHT (needed for KITTI calib.txt)");
  cmd->callback([args]() { RunCameraInfo(*args); });
}

}  // namespace retrace
