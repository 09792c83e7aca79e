#include "retrace/camera/calibration.h"

#include <algorithm>
#include <cctype>
#include <cfloat>
#include <cmath>
#include <limits>

#include <fmt/format.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/ccalib/omnidir.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include "retrace/camera/perspective_camera.h"
#include "retrace/camera/unified_camera.h"
#include "retrace/util/error.h"

namespace retrace {

bool ChessboardCalibrationOptions::Check() const {
  return board_size.width >= 2 && board_size.height >= 2 &&
         square_size > 0.0 && subpix_half_window >= 1 && min_images >= 3;
}

int ChessboardCalibrationResult::NumUsed() const {
  return static_cast<int>(std::count_if(images.begin(), images.end(), [](const auto& i) { return i.used; }));
}

bool DetectChessboardCorners(const cv::Mat& image, const ChessboardCalibrationOptions& options,
                             std::vector<cv::Point2f>* corners) {
  corners->clear();
  if (image.empty()) return false;
  cv::Mat gray;
  if (image.channels() == 3) {
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  } else if (image.channels() == 4) {
    cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
  } else {
    gray = image;
  }
  if (gray.depth() != CV_8U) gray.convertTo(gray, CV_8U);

  // The board is searched in an image of at most kMaxSearchSide pixels (both detectors slow down sharply with
  // size, to many seconds per megapixel image), then refined at full resolution.
  constexpr int kMaxSearchSide = 1000;
  const double scale = std::min(1.0, static_cast<double>(kMaxSearchSide) / std::max(gray.cols, gray.rows));
  cv::Mat search = gray;
  if (scale < 1.0) cv::resize(gray, search, cv::Size(), scale, scale, cv::INTER_AREA);
  // Classic quad-based detector first (fast check: quick rejection of views without a board); the sector-based
  // detector copes better with strong distortion (catadioptric and fisheye views) and blur.
  bool found = cv::findChessboardCorners(search, options.board_size, *corners,
                                         cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE |
                                             cv::CALIB_CB_FAST_CHECK);
  bool sector_based = false;
  if (!found) {
    corners->clear();
    found = cv::findChessboardCornersSB(search, options.board_size, *corners,
                                        cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_EXHAUSTIVE);
    sector_based = true;
  }
  if (!found || static_cast<int>(corners->size()) != options.board_size.area()) {
    corners->clear();
    return false;
  }
  // Back to full-resolution pixels (pixel centres at integers: x_full = (x_search + 0.5) / scale - 0.5).
  if (scale < 1.0) {
    for (cv::Point2f& corner : *corners) {
      corner = cv::Point2f(static_cast<float>((corner.x + 0.5) / scale - 0.5),
                           static_cast<float>((corner.y + 0.5) / scale - 0.5));
    }
  }
  // The refinement window must not reach the neighbouring corners: cap it at a third of the smallest spacing.
  double spacing = std::numeric_limits<double>::max();
  for (int row = 0; row < options.board_size.height; ++row) {
    for (int col = 0; col < options.board_size.width; ++col) {
      const int i = row * options.board_size.width + col;
      if (col + 1 < options.board_size.width) {
        spacing = std::min(spacing, static_cast<double>(cv::norm((*corners)[i + 1] - (*corners)[i])));
      }
      if (row + 1 < options.board_size.height) {
        spacing = std::min(spacing,
                           static_cast<double>(cv::norm((*corners)[i + options.board_size.width] - (*corners)[i])));
      }
    }
  }
  if (sector_based && scale < 1.0) {
    // Sector-based corners are refined best by the same detector at full resolution (its CALIB_CB_ACCURACY mode is
    // more robust than cornerSubPix on blurred, strongly curved catadioptric views); run it on the board's crop only.
    cv::Rect box = cv::boundingRect(*corners);
    const int margin = static_cast<int>(std::ceil(2.0 * spacing)) + 4;
    box = cv::Rect(box.x - margin, box.y - margin, box.width + 2 * margin, box.height + 2 * margin) &
          cv::Rect(0, 0, gray.cols, gray.rows);
    std::vector<cv::Point2f> refined;
    if (cv::findChessboardCornersSB(gray(box), options.board_size, refined,
                                    cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_EXHAUSTIVE | cv::CALIB_CB_ACCURACY) &&
        refined.size() == corners->size()) {
      for (cv::Point2f& corner : refined) corner += cv::Point2f(static_cast<float>(box.x), static_cast<float>(box.y));
      // Same board, possibly numbered from the other end.
      if (cv::norm(refined.front() - corners->front()) > cv::norm(refined.back() - corners->front())) {
        std::reverse(refined.begin(), refined.end());
      }
      double max_shift = 0.0;
      for (size_t i = 0; i < refined.size(); ++i) {
        max_shift = std::max(max_shift, static_cast<double>(cv::norm(refined[i] - (*corners)[i])));
      }
      if (max_shift < 0.5 * spacing) {
        *corners = refined;
        return true;
      }
    }
  }
  const int half_window =
      std::max(2, std::min(options.subpix_half_window, static_cast<int>(std::floor(spacing / 3.0))));
  cv::cornerSubPix(gray, *corners, cv::Size(half_window, half_window), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 0.001));
  return true;
}

namespace {

// Accumulates per-image detections, then runs the estimation.
class Calibrator {
 public:
  Calibrator(const ChessboardCalibrationOptions& options, std::string source)
      : options_(options), source_(std::move(source)) {
    if (!options_.Check()) {
      throw std::invalid_argument(fmt::format(
          "invalid chessboard calibration options (board {}x{} must be at least 2x2, square size > 0)",
          options_.board_size.width, options_.board_size.height));
    }
    for (int row = 0; row < options_.board_size.height; ++row) {
      for (int col = 0; col < options_.board_size.width; ++col) {
        board_.emplace_back(col * options_.square_size, row * options_.square_size, 0.0);
      }
    }
  }

  void Add(const cv::Mat& image, const std::string& name) {
    CalibrationImage report;
    report.name = name;
    std::vector<cv::Point2f> corners;
    if (image.empty()) {
      report.reason = "cannot read image";
    } else if (!image_size_.empty() && image.size() != image_size_) {
      report.reason = fmt::format("image size {}x{} differs from the first image's {}x{}", image.cols, image.rows,
                                  image_size_.width, image_size_.height);
    } else if (!DetectChessboardCorners(image, options_, &corners)) {
      report.reason = fmt::format("{}x{} chessboard not found", options_.board_size.width, options_.board_size.height);
    } else {
      image_size_ = image.size();
      report.used = true;
      corners_.push_back(corners);
      index_.push_back(result_.images.size());
    }
    if (report.used) {
      spdlog::debug("{}: chessboard found", name);
    } else {
      spdlog::warn("{}: skipped: {}", name, report.reason);
    }
    result_.images.push_back(report);
  }

  ChessboardCalibrationResult Finish() {
    if (static_cast<int>(corners_.size()) < options_.min_images) {
      throw InputError(source_, fmt::format("only {} of {} images show the {}x{} chessboard, need at least {}",
                                            corners_.size(), result_.images.size(), options_.board_size.width,
                                            options_.board_size.height, options_.min_images));
    }
    if (options_.model == CalibrationModel::kPerspective) {
      CalibratePerspective();
    } else {
      CalibrateUnified();
    }
    return std::move(result_);
  }

 private:
  void CalibratePerspective() {
    const std::vector<std::vector<cv::Point3f>> object_points(corners_.size(), board_);
    cv::Mat k = cv::Mat::eye(3, 3, CV_64F), distortion, std_intrinsics, std_extrinsics, per_view_errors;
    std::vector<cv::Mat> rvecs, tvecs;
    int flags = 0;
    if (!options_.estimate_k3) flags |= cv::CALIB_FIX_K3;
    if (options_.fix_aspect_ratio) flags |= cv::CALIB_FIX_ASPECT_RATIO;
    result_.rms_error_px =
        cv::calibrateCamera(object_points, corners_, image_size_, k, distortion, rvecs, tvecs, std_intrinsics,
                            std_extrinsics, per_view_errors, flags,
                            cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, DBL_EPSILON));
    // OpenCV's calibrateCamera has no skew; options_.estimate_skew applies to the unified model only.
    const cv::Mat d = distortion.reshape(1, 1);
    LensDistortion lens;
    lens.k1 = d.at<double>(0);
    lens.k2 = d.at<double>(1);
    lens.p1 = d.at<double>(2);
    lens.p2 = d.at<double>(3);
    lens.k3 = d.cols > 4 ? d.at<double>(4) : 0.0;
    result_.camera = std::make_unique<PerspectiveCamera>(image_size_.width, image_size_.height, k.at<double>(0, 0),
                                                         k.at<double>(1, 1), k.at<double>(0, 2), k.at<double>(1, 2),
                                                         0.0, lens);
    for (size_t i = 0; i < index_.size(); ++i) {
      result_.images[index_[i]].rms_error_px = per_view_errors.at<double>(static_cast<int>(i));
    }
  }

  void CalibrateUnified() {
    std::vector<cv::Mat> object_points, image_points;
    for (const auto& corners : corners_) {
      cv::Mat object(1, static_cast<int>(board_.size()), CV_64FC3);
      cv::Mat image(1, static_cast<int>(corners.size()), CV_64FC2);
      for (size_t j = 0; j < corners.size(); ++j) {
        object.at<cv::Vec3d>(0, static_cast<int>(j)) = cv::Vec3d(board_[j].x, board_[j].y, board_[j].z);
        image.at<cv::Vec2d>(0, static_cast<int>(j)) = cv::Vec2d(corners[j].x, corners[j].y);
      }
      object_points.push_back(object);
      image_points.push_back(image);
    }
    cv::Mat k, xi, distortion, used;
    std::vector<cv::Mat> rvecs, tvecs;
    int flags = options_.estimate_skew ? 0 : cv::omnidir::CALIB_FIX_SKEW;
    // Mei 2007: initialisation from the planar grid, then Levenberg-Marquardt on all parameters (cv::omnidir).
    result_.rms_error_px =
        cv::omnidir::calibrate(object_points, image_points, image_size_, k, xi, distortion, rvecs, tvecs, flags,
                               cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 300, 1e-8), used);
    if (k.empty() || used.empty()) {
      throw InputError(source_, "the unified-model calibration could not initialise from these views");
    }
    const cv::Mat d = distortion.reshape(1, 1);
    LensDistortion lens;
    lens.k1 = d.at<double>(0);
    lens.k2 = d.at<double>(1);
    lens.p1 = d.at<double>(2);
    lens.p2 = d.at<double>(3);
    const double xi_value = xi.reshape(1, 1).at<double>(0);
    result_.camera = std::make_unique<UnifiedCamera>(image_size_.width, image_size_.height, xi_value,
                                                     k.at<double>(0, 0), k.at<double>(1, 1), k.at<double>(0, 2),
                                                     k.at<double>(1, 2), k.at<double>(0, 1), lens);
    // Views the initialisation rejected are reported as skipped; the others get their own RMS.
    const cv::Mat used_index = used.reshape(1, 1);
    std::vector<bool> kept(index_.size(), false);
    for (int j = 0; j < used_index.cols; ++j) {
      const int view = used_index.type() == CV_32S ? used_index.at<int>(j) : static_cast<int>(used_index.at<double>(j));
      if (view < 0 || view >= static_cast<int>(index_.size()) || j >= static_cast<int>(rvecs.size())) continue;
      kept[view] = true;
      cv::Mat projected;
      cv::omnidir::projectPoints(object_points[view], projected, rvecs[j], tvecs[j], k, xi_value, distortion);
      double sum = 0.0;
      for (int c = 0; c < projected.cols * projected.rows; ++c) {
        const cv::Vec2d diff = projected.at<cv::Vec2d>(c) - image_points[view].at<cv::Vec2d>(c);
        sum += diff.dot(diff);
      }
      result_.images[index_[view]].rms_error_px = std::sqrt(sum / board_.size());
    }
    for (size_t view = 0; view < index_.size(); ++view) {
      if (kept[view]) continue;
      CalibrationImage& report = result_.images[index_[view]];
      report.used = false;
      report.reason = "rejected by the unified-model initialisation";
      spdlog::warn("{}: skipped: {}", report.name, report.reason);
    }
  }

  ChessboardCalibrationOptions options_;
  std::string source_;
  std::vector<cv::Point3f> board_;
  cv::Size image_size_;
  std::vector<std::vector<cv::Point2f>> corners_;
  std::vector<size_t> index_;  // result_.images index of each entry of corners_
  ChessboardCalibrationResult result_;
};

}  // namespace

ChessboardCalibrationResult CalibrateChessboard(const std::vector<cv::Mat>& images,
                                                const std::vector<std::string>& names,
                                                const ChessboardCalibrationOptions& options,
                                                const std::string& source) {
  if (images.size() != names.size()) throw std::invalid_argument("CalibrateChessboard: one name per image needed");
  Calibrator calibrator(options, source);
  for (size_t i = 0; i < images.size(); ++i) calibrator.Add(images[i], names[i]);
  return calibrator.Finish();
}

std::vector<std::filesystem::path> ListImageFiles(const std::filesystem::path& folder) {
  std::error_code error;
  if (!std::filesystem::is_directory(folder, error)) {
    throw InputError(folder.string(), std::filesystem::exists(folder, error) ? "not a folder" : "folder not found");
  }
  static const char* kExtensions[] = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm"};
  std::vector<std::filesystem::path> files;
  for (const auto& entry : std::filesystem::directory_iterator(folder, error)) {
    if (!entry.is_regular_file()) continue;
    std::string extension = entry.path().extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (std::find(std::begin(kExtensions), std::end(kExtensions), extension) != std::end(kExtensions)) {
      files.push_back(entry.path());
    }
  }
  if (error) throw InputError(folder.string(), "cannot list folder (" + error.message() + ")");
  if (files.empty()) throw InputError(folder.string(), "no image files (png, jpg, bmp, tif, pgm, ppm) in folder");
  std::sort(files.begin(), files.end());
  return files;
}

ChessboardCalibrationResult CalibrateChessboardFolder(const std::filesystem::path& folder,
                                                      const ChessboardCalibrationOptions& options) {
  const std::vector<std::filesystem::path> files = ListImageFiles(folder);
  Calibrator calibrator(options, folder.string());
  for (const auto& file : files) {
    cv::Mat image;
    try {
      image = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
    } catch (const cv::Exception&) {
      image.release();
    }
    calibrator.Add(image, file.filename().string());
  }
  return calibrator.Finish();
}

}  // namespace retrace
