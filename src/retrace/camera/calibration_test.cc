#include "retrace/camera/calibration.h"

#include <cmath>
#include <fstream>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "retrace/camera/camera_io.h"
#include "retrace/camera/perspective_camera.h"
#include "retrace/camera/unified_camera.h"
#include "retrace/util/error.h"
#include "retrace/util/testing.h"

namespace retrace {
namespace {

// Renders a chessboard with `inner` inner corners (square side `square`, corner (i, j) at board point
// (i square, j square, 0)) seen from `cam_from_board` through `camera`, by casting each pixel's ray onto the board
// plane. Edges are anti-aliased with the pixel's footprint on the board, so corners are exact to sub-pixel level.
class ChessboardRenderer {
 public:
  explicit ChessboardRenderer(const CameraModel& camera) : width_(camera.width()), height_(camera.height()) {
    bearings_.resize(static_cast<size_t>(width_) * height_, Vector3d::Zero());
    for (int y = 0; y < height_; ++y) {
      for (int x = 0; x < width_; ++x) {
        Vector3d bearing;
        if (camera.Unproject(Vector2d(x, y), &bearing)) bearings_[y * width_ + x] = bearing;
      }
    }
  }

  // `covered` (optional, CV_8U of the image size) gets 255 where the squares of the board are seen.
  cv::Mat Render(const Rigid3d& cam_from_board, cv::Size inner, double square, std::mt19937* rng,
                 cv::Mat* covered = nullptr) const {
    if (covered && covered->empty()) *covered = cv::Mat::zeros(height_, width_, CV_8U);
    const Matrix3d& r = cam_from_board.rotation;
    const Vector3d& t = cam_from_board.translation;
    const Vector3d normal = r.col(2);
    // Board coordinates (in squares) of every pixel's ray, NaN when the ray misses the plane.
    cv::Mat uv(height_, width_, CV_64FC2, cv::Scalar(NAN, NAN));
    for (int y = 0; y < height_; ++y) {
      for (int x = 0; x < width_; ++x) {
        const Vector3d& d = bearings_[y * width_ + x];
        const double denominator = normal.dot(d);
        if (d.isZero() || std::abs(denominator) < 1e-9) continue;
        const double lambda = normal.dot(t) / denominator;
        if (lambda <= 0.0) continue;
        const Vector3d on_board = r.transpose() * (lambda * d - t);
        uv.at<cv::Vec2d>(y, x) = cv::Vec2d(on_board.x() / square, on_board.y() / square);
      }
    }
    constexpr double kBlack = 25, kWhite = 225, kBackground = 110;
    std::normal_distribution<double> noise(0.0, 1.5);
    cv::Mat image(height_, width_, CV_8U);
    for (int y = 0; y < height_; ++y) {
      for (int x = 0; x < width_; ++x) {
        const cv::Vec2d p = uv.at<cv::Vec2d>(y, x);
        double value = kBackground;
        if (!std::isnan(p[0]) && x > 0 && y > 0 && x + 1 < width_ && y + 1 < height_) {
          const cv::Vec2d dx = 0.5 * (uv.at<cv::Vec2d>(y, x + 1) - uv.at<cv::Vec2d>(y, x - 1));
          const cv::Vec2d dy = 0.5 * (uv.at<cv::Vec2d>(y + 1, x) - uv.at<cv::Vec2d>(y - 1, x));
          const double wu = std::abs(dx[0]) + std::abs(dy[0]), wv = std::abs(dx[1]) + std::abs(dy[1]);
          if (std::isfinite(wu) && std::isfinite(wv)) {
            // Box-filtered indicator of the interval [lo, hi] along one axis and the alternating square pattern.
            const auto box = [](double s, double w, double lo, double hi) {
              return std::clamp((s - lo) / w + 0.5, 0.0, 1.0) * std::clamp((hi - s) / w + 0.5, 0.0, 1.0);
            };
            const auto alternate = [](double s, double w) {
              const double n = std::round(s);
              const double sign = std::fmod(std::abs(n), 2.0) == 0.0 ? 1.0 : -1.0;
              return sign * 2.0 * std::clamp((s - n) / w, -0.5, 0.5);
            };
            const double in_squares = box(p[0], wu, -1, inner.width) * box(p[1], wv, -1, inner.height);
            const double in_board = box(p[0], wu, -2, inner.width + 1) * box(p[1], wv, -2, inner.height + 1);
            const double checker = 0.5 + 0.5 * alternate(p[0], wu) * alternate(p[1], wv);  // 1 = white
            const double board_value = in_squares * (kBlack + checker * (kWhite - kBlack)) + (1 - in_squares) * kWhite;
            value = in_board * board_value + (1 - in_board) * kBackground;
            if (covered && in_squares > 0.0) covered->at<uint8_t>(y, x) = 255;
          }
        }
        image.at<uint8_t>(y, x) = cv::saturate_cast<uint8_t>(value + noise(*rng));
      }
    }
    return image;
  }

 private:
  int width_, height_;
  std::vector<Vector3d> bearings_;
};

Matrix3d RotationXYZ(double ax, double ay, double az) {
  return (Eigen::AngleAxisd(ax, Vector3d::UnitX()) * Eigen::AngleAxisd(ay, Vector3d::UnitY()) *
          Eigen::AngleAxisd(az, Vector3d::UnitZ()))
      .toRotationMatrix();
}

// `count` board poses, tilted up to ~35 degrees, spread over the image, with the whole board (and its white
// margin) inside the image.
std::vector<Rigid3d> BoardPoses(const CameraModel& camera, cv::Size inner, double square, double min_depth,
                                double max_depth, int count, std::mt19937* rng) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::uniform_real_distribution<double> depth(min_depth, max_depth);
  std::vector<Rigid3d> poses;
  while (static_cast<int>(poses.size()) < count) {
    const Matrix3d rotation = RotationXYZ(0.6 * unit(*rng), 0.6 * unit(*rng), 0.3 * unit(*rng));
    Vector3d direction;
    const Vector2d target(camera.width() * (0.5 + 0.25 * unit(*rng)), camera.height() * (0.5 + 0.25 * unit(*rng)));
    if (!camera.Unproject(target, &direction)) continue;
    const Vector3d board_centre(0.5 * (inner.width - 1) * square, 0.5 * (inner.height - 1) * square, 0.0);
    const Rigid3d cam_from_board(rotation, depth(*rng) / direction.z() * direction - rotation * board_centre);
    bool inside = true;
    for (const double u : {-2.0, inner.width + 1.0}) {
      for (const double v : {-2.0, inner.height + 1.0}) {
        Vector2d pixel;
        inside = inside && camera.Project(cam_from_board * Vector3d(u * square, v * square, 0.0), &pixel) &&
                 camera.InImage(pixel, 8.0);
      }
    }
    if (inside) poses.push_back(cam_from_board);
  }
  return poses;
}

PerspectiveCamera TrueCamera() {
  LensDistortion d;
  d.k1 = -0.28;
  d.k2 = 0.09;
  d.p1 = 0.0008;
  d.p2 = -0.0005;
  return PerspectiveCamera(640, 480, 520.0, 515.0, 322.5, 237.8, 0.0, d);
}

// Largest distance between the pixels two cameras give the same rays, over the pixels of `truth` where `covered` is
// set (calibration only constrains the model where the board was seen).
double MaxProjectionDifferencePx(const CameraModel& truth, const CameraModel& estimate, const cv::Mat& covered) {
  double max_difference = 0.0;
  for (int y = 0; y < truth.height(); y += 8) {
    for (int x = 0; x < truth.width(); x += 8) {
      Vector3d bearing;
      Vector2d pixel;
      if (!covered.at<uint8_t>(y, x) || !truth.Unproject(Vector2d(x, y), &bearing)) continue;
      if (!estimate.Project(bearing, &pixel)) return INFINITY;
      max_difference = std::max(max_difference, (pixel - Vector2d(x, y)).norm());
    }
  }
  return max_difference;
}

TEST(ChessboardCalibration, RecoversSyntheticPerspectiveCamera) {
  const PerspectiveCamera truth = TrueCamera();
  const ChessboardRenderer renderer(truth);
  ChessboardCalibrationOptions options;
  options.board_size = cv::Size(9, 6);
  options.square_size = 0.03;
  std::mt19937 rng(42);
  std::vector<cv::Mat> images;
  cv::Mat covered;
  std::vector<std::string> names;
  for (const Rigid3d& pose : BoardPoses(truth, options.board_size, options.square_size, 0.35, 0.6, 10, &rng)) {
    images.push_back(renderer.Render(pose, options.board_size, options.square_size, &rng, &covered));
    names.push_back("view" + std::to_string(images.size()));
  }
  // Two images without a usable board: they must be reported and skipped.
  images.push_back(cv::Mat(480, 640, CV_8U, cv::Scalar(110)));
  names.push_back("blank");
  images.push_back(cv::Mat());
  names.push_back("unreadable");

  const ChessboardCalibrationResult result = CalibrateChessboard(images, names, options, "synthetic");
  ASSERT_NE(result.camera, nullptr);
  ASSERT_EQ(result.images.size(), 12u);
  EXPECT_EQ(result.NumUsed(), 10);
  EXPECT_FALSE(result.images[10].used);
  EXPECT_NE(result.images[10].reason.find("chessboard not found"), std::string::npos);
  EXPECT_FALSE(result.images[11].used);
  EXPECT_EQ(result.images[11].reason, "cannot read image");
  for (int i = 0; i < 10; ++i) {
    EXPECT_TRUE(result.images[i].used) << names[i] << ": " << result.images[i].reason;
    EXPECT_GT(result.images[i].rms_error_px, 0.0);
    EXPECT_LT(result.images[i].rms_error_px, 0.2);
  }
  const auto& estimate = dynamic_cast<const PerspectiveCamera&>(*result.camera);
  const auto relative = [](double a, double b) { return std::abs(a - b) / std::abs(b); };
  std::printf("synthetic perspective: rms %.4f px, fx %.3f (%.4f%%) fy %.3f (%.4f%%) cx %.3f (%.4f%%) cy %.3f "
              "(%.4f%%), k1 %.4f k2 %.4f k3 %.4f p1 %.5f p2 %.5f, max projection difference %.3f px\n",
              result.rms_error_px, estimate.fx(), 100 * relative(estimate.fx(), truth.fx()), estimate.fy(),
              100 * relative(estimate.fy(), truth.fy()), estimate.cx(), 100 * relative(estimate.cx(), truth.cx()),
              estimate.cy(), 100 * relative(estimate.cy(), truth.cy()), estimate.distortion().k1,
              estimate.distortion().k2, estimate.distortion().k3, estimate.distortion().p1, estimate.distortion().p2,
              MaxProjectionDifferencePx(truth, estimate, covered));
  EXPECT_LT(result.rms_error_px, 0.2);
  EXPECT_LT(relative(estimate.fx(), truth.fx()), 0.01);
  EXPECT_LT(relative(estimate.fy(), truth.fy()), 0.01);
  EXPECT_LT(relative(estimate.cx(), truth.cx()), 0.01);
  EXPECT_LT(relative(estimate.cy(), truth.cy()), 0.01);
  // The whole model (K and distortion together) maps rays to the same pixels where the board was seen.
  EXPECT_LT(MaxProjectionDifferencePx(truth, estimate, covered), 0.5);
}

TEST(ChessboardCalibration, FolderInputSkipsBadFilesAndNamesTheFolderOnFailure) {
  const PerspectiveCamera truth = TrueCamera();
  const ChessboardRenderer renderer(truth);
  ChessboardCalibrationOptions options;
  options.square_size = 0.03;
  std::mt19937 rng(5);
  const std::filesystem::path dir = testing::MakeTempDir("calibration_test");
  int index = 0;
  for (const Rigid3d& pose : BoardPoses(truth, options.board_size, options.square_size, 0.35, 0.6, 3, &rng)) {
    cv::imwrite((dir / ("board" + std::to_string(index++) + ".png")).string(),
                renderer.Render(pose, options.board_size, options.square_size, &rng));
  }
  std::ofstream(dir / "broken.png") << "not a png";
  std::ofstream(dir / "notes.txt") << "ignored";
  try {
    CalibrateChessboardFolder(dir, options);  // 3 good images, min_images = 4
    ADD_FAILURE() << "calibrated from too few images";
  } catch (const InputError& e) {
    EXPECT_EQ(e.source(), dir.string());
    EXPECT_NE(std::string(e.what()).find("only 3 of 4 images show the 9x6 chessboard"), std::string::npos)
        << e.what();
  }
  options.min_images = 3;
  const ChessboardCalibrationResult result = CalibrateChessboardFolder(dir, options);
  ASSERT_EQ(result.images.size(), 4u);  // notes.txt is not an image
  EXPECT_EQ(result.images[3].name, "broken.png");
  EXPECT_FALSE(result.images.front().name != "board0.png");
  EXPECT_EQ(result.NumUsed(), 3);
  const auto find_broken = std::find_if(result.images.begin(), result.images.end(),
                                        [](const CalibrationImage& image) { return image.name == "broken.png"; });
  ASSERT_NE(find_broken, result.images.end());
  EXPECT_EQ(find_broken->reason, "cannot read image");
  std::filesystem::remove_all(dir);

  EXPECT_THROW(CalibrateChessboardFolder(dir / "missing", options), InputError);
  const std::filesystem::path empty = testing::MakeTempDir("calibration_test_empty");
  try {
    CalibrateChessboardFolder(empty, options);
    ADD_FAILURE() << "empty folder accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no image files"), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(empty);
}

TEST(ChessboardCalibration, RecoversSyntheticUnifiedCamera) {
  LensDistortion d;
  d.k1 = -0.05;
  d.k2 = 0.01;
  d.p1 = 0.0004;
  d.p2 = -0.0003;
  const UnifiedCamera truth(752, 480, 1.1, 620.0, 618.0, 378.5, 241.2, 0.0, d);
  const ChessboardRenderer renderer(truth);
  ChessboardCalibrationOptions options;
  options.square_size = 0.03;
  options.model = CalibrationModel::kUnified;
  std::mt19937 rng(11);
  std::vector<cv::Mat> images;
  cv::Mat covered;
  std::vector<std::string> names;
  for (const Rigid3d& pose : BoardPoses(truth, options.board_size, options.square_size, 0.25, 0.45, 12, &rng)) {
    images.push_back(renderer.Render(pose, options.board_size, options.square_size, &rng, &covered));
    names.push_back("view" + std::to_string(images.size()));
  }
  const ChessboardCalibrationResult result = CalibrateChessboard(images, names, options, "synthetic");
  ASSERT_NE(result.camera, nullptr);
  ASSERT_EQ(result.camera->type(), CameraModelType::kUnified);
  const auto& estimate = dynamic_cast<const UnifiedCamera&>(*result.camera);
  const double difference = MaxProjectionDifferencePx(truth, estimate, covered);
  std::printf("synthetic unified: %d of %zu views used, rms %.4f px, xi %.4f (true %.4f), fx %.2f fy %.2f cx %.2f "
              "cy %.2f, max projection difference %.3f px over %.0f%% of the image\n",
              result.NumUsed(), result.images.size(), result.rms_error_px, estimate.xi(), truth.xi(), estimate.fx(),
              estimate.fy(), estimate.cx(), estimate.cy(), difference, 100.0 * cv::countNonZero(covered) / covered.total());
  EXPECT_GE(result.NumUsed(), 8);
  EXPECT_LT(result.rms_error_px, 0.2);
  // xi and f are strongly correlated (Mei 2007), so compare the principal point and the ray-to-pixel mapping.
  EXPECT_LT(std::abs(estimate.cx() - truth.cx()), 0.01 * truth.cx());
  EXPECT_LT(std::abs(estimate.cy() - truth.cy()), 0.01 * truth.cy());
  EXPECT_LT(difference, 0.5);
}

TEST(ChessboardCalibration, RealOpenCvSampleMatchesOpenCvResult) {
  RETRACE_REQUIRE_SHARED_DATA(folder, "chessboard_640x480/left");
  RETRACE_REQUIRE_SHARED_DATA(reference_file, "chessboard_640x480/left_intrinsics.yml");
  ChessboardCalibrationOptions options;
  options.board_size = cv::Size(9, 6);
  options.square_size = 0.025;
  const ChessboardCalibrationResult result = CalibrateChessboardFolder(folder, options);
  const auto reference_camera = ReadCameraFile(reference_file);
  const auto& reference = dynamic_cast<const PerspectiveCamera&>(*reference_camera);
  const auto& estimate = dynamic_cast<const PerspectiveCamera&>(*result.camera);
  const auto relative = [](double a, double b) { return std::abs(a - b) / std::abs(b); };
  std::printf("real left/: %d of %zu images, rms %.4f px; fx %.3f (%.3f%%) fy %.3f (%.3f%%) cx %.3f (%.3f%%) "
              "cy %.3f (%.3f%%)\n",
              result.NumUsed(), result.images.size(), result.rms_error_px, estimate.fx(),
              100 * relative(estimate.fx(), reference.fx()), estimate.fy(), 100 * relative(estimate.fy(), reference.fy()),
              estimate.cx(), 100 * relative(estimate.cx(), reference.cx()), estimate.cy(),
              100 * relative(estimate.cy(), reference.cy()));
  EXPECT_EQ(result.camera->width(), 640);
  EXPECT_EQ(result.camera->height(), 480);
  EXPECT_GE(result.NumUsed(), 12);
  EXPECT_LT(result.rms_error_px, 0.5);
  EXPECT_LT(relative(estimate.fx(), reference.fx()), 0.02);
  EXPECT_LT(relative(estimate.fy(), reference.fy()), 0.02);
  EXPECT_LT(relative(estimate.cx(), reference.cx()), 0.02);
  EXPECT_LT(relative(estimate.cy(), reference.cy()), 0.02);
}

TEST(ChessboardCalibration, RealCatadioptricMeiImages) {
  // C. Mei's own catadioptric sample images (1280x1024, 8x6 inner corners). There is no reference calibration, so
  // this checks the fit (RMS) and physically plausible parameters: a mirror camera has xi near 1 and its principal
  // point near the centre of the mirror, which the images show close to the image centre.
  RETRACE_REQUIRE_SHARED_DATA(folder, "omni_calib/catadioptric_Mei");
  ChessboardCalibrationOptions options;
  options.board_size = cv::Size(8, 6);
  options.model = CalibrationModel::kUnified;
  const ChessboardCalibrationResult result = CalibrateChessboardFolder(folder, options);
  ASSERT_EQ(result.camera->type(), CameraModelType::kUnified);
  const auto& camera = dynamic_cast<const UnifiedCamera&>(*result.camera);
  std::printf("real catadioptric_Mei: %d of %zu images, rms %.4f px, xi %.4f fx %.2f fy %.2f cx %.2f cy %.2f\n",
              result.NumUsed(), result.images.size(), result.rms_error_px, camera.xi(), camera.fx(), camera.fy(),
              camera.cx(), camera.cy());
  EXPECT_GE(result.NumUsed(), 7);
  EXPECT_LT(result.rms_error_px, 0.5);
  EXPECT_GT(camera.xi(), 0.7);
  EXPECT_LT(camera.xi(), 1.4);
  EXPECT_LT(std::abs(camera.cx() - 639.5), 20.0);
  EXPECT_LT(std::abs(camera.cy() - 511.5), 20.0);
}

}  // namespace
}  // namespace retrace
