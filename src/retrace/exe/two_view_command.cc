// `retrace two-view IMG_A IMG_B --camera CAM [--json]`: relative pose of two images — SIFT matches, robust 5-point
// (or planar) estimation on bearings, σ_p (Segvic 2009, eq. 6).

#include <filesystem>
#include <iostream>
#include <memory>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgcodecs.hpp>

#include "retrace/camera/camera_io.h"
#include "retrace/exe/commands.h"
#include "retrace/geometry/planar_pose.h"
#include "retrace/geometry/relative_pose.h"
#include "retrace/geometry/two_view_matching.h"
#include "retrace/util/error.h"

namespace retrace {
namespace {

struct TwoViewArgs {
  std::string image_a;
  std::string image_b;
  std::string camera;
  bool json = false;
  bool planar = false;
  double max_error_px = TwoViewOptions().ransac.max_error_px;
  double ratio = TwoViewMatchingOptions().ratio;
};

cv::Mat ReadImage(const std::string& path) {
  // Checked first so that OpenCV does not print its own warning next to our one-line error.
  std::error_code error;
  if (!std::filesystem::is_regular_file(path, error)) throw InputError(path, "cannot read image (no such file)");
  cv::Mat image = cv::imread(path, cv::IMREAD_GRAYSCALE);
  if (image.empty()) throw InputError(path, "cannot read image");
  return image;
}

void RunTwoView(const TwoViewArgs& args) {
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_ERROR);  // decoder warnings would break one-line errors
  const cv::Mat image_a = ReadImage(args.image_a);
  const cv::Mat image_b = ReadImage(args.image_b);
  if (image_b.size() != image_a.size()) {
    throw InputError(args.image_b, fmt::format("image size {}x{} differs from {}x{} of {}", image_b.cols,
                                               image_b.rows, image_a.cols, image_a.rows, args.image_a));
  }
  // Calibration files without an image size (KITTI calib.txt) take the size of the first image.
  const std::unique_ptr<CameraModel> camera = ReadCameraFile(args.camera, image_a.size());

  TwoViewMatchingOptions matching;
  matching.ratio = args.ratio;
  const PixelMatches matches = MatchTwoViewFeatures(image_a, image_b, matching);
  std::vector<Vector3d> bearings_a, bearings_b;
  MatchesToBearings(matches, *camera, *camera, &bearings_a, &bearings_b);

  TwoViewOptions options;
  options.ransac.max_error_px = args.max_error_px;
  const TwoViewGeometry g = args.planar
                                ? EstimatePlanarRelativePose(bearings_a, bearings_b, camera->FocalLength(), options)
                                : EstimateRelativePose(bearings_a, bearings_b, camera->FocalLength(), options);
  if (!g.success) {
    throw std::runtime_error(fmt::format("no two-view geometry between {} and {} ({} matches): {}", args.image_a,
                                         args.image_b, bearings_a.size(), g.failure_message));
  }
  const Matrix3d& r = g.b_from_a.rotation;
  const Vector3d& t = g.b_from_a.translation;
  if (args.json) {
    nlohmann::json out;
    out["R"] = {r(0, 0), r(0, 1), r(0, 2), r(1, 0), r(1, 1), r(1, 2), r(2, 0), r(2, 1), r(2, 2)};
    out["t"] = {t.x(), t.y(), t.z()};
    out["inliers"] = g.num_inliers;
    out["sigma_p"] = g.sigma_p;
    // Booij 2007 eq. (B.4) in retrace's axes (geometry/planar_pose.h PlanarHeading): the direction of B's centre
    // seen from A, radians, 0 = straight ahead, positive = to the right, ±π = behind.
    if (args.planar) out["heading"] = PlanarHeading(g.b_from_a);
    std::cout << out.dump() << "\n";
    return;
  }
  std::cout << fmt::format("model:     {}\n", args.planar ? "planar motion (rotation about y)" : "5-point");
  std::cout << fmt::format("matches:   {}\n", bearings_a.size());
  std::cout << fmt::format("inliers:   {}\n", g.num_inliers);
  std::cout << fmt::format("sigma_p:   {:.3f} px (rms residual {:.3f} px, median parallax {:.1f} px)\n", g.sigma_p,
                           g.rms_residual_px, g.median_parallax_px);
  std::cout << "R (x_B = R x_A + t):\n";
  for (int i = 0; i < 3; ++i) {
    std::cout << fmt::format("  {:+.6f} {:+.6f} {:+.6f}\n", r(i, 0), r(i, 1), r(i, 2));
  }
  std::cout << fmt::format("t (unit):  {:+.6f} {:+.6f} {:+.6f}\n", t.x(), t.y(), t.z());
  std::cout << fmt::format("rotation:  {:.3f} deg\n", Eigen::AngleAxisd(r).angle() * 180.0 / M_PI);
  std::cout << fmt::format("heading:   {:.2f} deg towards B (0 = ahead, + = right)\n",
                           PlanarHeading(g.b_from_a) * 180.0 / M_PI);
}

}  // namespace

void RegisterTwoViewCommand(CLI::App& app) {
  auto args = std::make_shared<TwoViewArgs>();
  CLI::App* cmd = app.add_subcommand(
      "two-view", "Relative pose (R, unit t, x_B = R x_A + t) of two images from SIFT matches, with sigma_p");
  cmd->add_option("image_a", args->image_a, "First image (A)")->required();
  cmd->add_option("image_b", args->image_b, "Second image (B)")->required();
  cmd->add_option("--camera", args->camera, "Calibration file (ROS/OpenCV YAML, KITTI calib.txt, EuRoC sensor.yaml)")
      ->required();
  cmd->add_flag("--json", args->json, "Print one JSON object {R: [9, row-major], t: [3], inliers, sigma_p}; with --planar also heading: "
                "the direction of B from A in radians (Booij 2007 eq. B.4 in retrace's axes: atan2(c_x, c_z) of B's "
                "centre c in A's frame; 0 = ahead, + = right)");
  cmd->add_flag("--planar", args->planar, "Planar-motion model (Booij 2007): rotation about the camera y axis only");
  cmd->add_option("--max-error", args->max_error_px, "Inlier threshold on the Sampson error, pixels")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--ratio", args->ratio, "Ratio test of the SIFT matching")->check(CLI::Range(0.1, 1.0));
  cmd->callback([args]() { RunTwoView(*args); });
}

}  // namespace retrace
