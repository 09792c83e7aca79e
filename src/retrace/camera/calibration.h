#pragma once

// Intrinsic calibration from chessboard images (Zhang's method as implemented by OpenCV).
//
// Every image is searched for the board's inner corners (cv::findChessboardCorners, with cv::findChessboardCornersSB
// as a fallback for strongly distorted views; images larger than 1000 px are searched at reduced size), refined at
// full resolution by cv::cornerSubPix. The perspective model is then estimated
// by cv::calibrateCamera (K + plumb bob distortion), the unified model (Mei 2007) by cv::omnidir::calibrate. Images
// that cannot be read, have another size than the first one, or where the board is not found are skipped, logged
// (spdlog warn, with the file name) and listed with the reason in the result.

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "retrace/camera/camera_model.h"

namespace retrace {

enum class CalibrationModel {
  kPerspective,  // PerspectiveCamera: fx, fy, cx, cy + k1, k2, p1, p2 (+ k3)
  kUnified,      // UnifiedCamera: xi, fx, fy, cx, cy + k1, k2, p1, p2 (cv::omnidir)
};

struct ChessboardCalibrationOptions {
  // Inner corners of the board, columns x rows (OpenCV's sample board: 9x6).
  cv::Size board_size{9, 6};
  // Side of one square, in the unit the board poses should have (e.g. metres). Intrinsics do not depend on it.
  double square_size = 1.0;
  // Camera model to estimate.
  CalibrationModel model = CalibrationModel::kPerspective;
  // Perspective model: also estimate the sixth-order radial coefficient k3 (OpenCV's default).
  bool estimate_k3 = true;
  // Perspective model: force fx = fy.
  bool fix_aspect_ratio = false;
  // Estimate the skew of K (almost always zero for real sensors).
  bool estimate_skew = false;
  // Half size of the cornerSubPix search window in pixels (OpenCV's calibration sample uses 11).
  int subpix_half_window = 11;
  // Fewest images with a detected board needed to calibrate; fewer is an input error.
  int min_images = 4;

  bool Check() const;
};

// What happened to one input image.
struct CalibrationImage {
  std::string name;            // file name (or the caller's name for in-memory images)
  bool used = false;           // contributed to the calibration
  std::string reason;          // why it was skipped; empty when used
  double rms_error_px = -1.0;  // RMS reprojection error of its corners when used
};

struct ChessboardCalibrationResult {
  std::unique_ptr<CameraModel> camera;
  double rms_error_px = 0.0;             // RMS reprojection error over all corners of the used images
  std::vector<CalibrationImage> images;  // every input image, in input order

  int NumUsed() const;
};

// Finds the board's inner corners in a grey or colour image, refined to sub-pixel precision. Returns false when
// the whole board is not found.
bool DetectChessboardCorners(const cv::Mat& image, const ChessboardCalibrationOptions& options,
                             std::vector<cv::Point2f>* corners);

// Calibrates from images in memory; `names` label them in the report (same length as `images`), `source` names the
// input in errors. Throws InputError(source, ...) when fewer than options.min_images images show the board.
ChessboardCalibrationResult CalibrateChessboard(const std::vector<cv::Mat>& images,
                                                const std::vector<std::string>& names,
                                                const ChessboardCalibrationOptions& options,
                                                const std::string& source = "images");

// Calibrates from every image file in `folder` (png, jpg, jpeg, bmp, tif, tiff, pgm, ppm; in name order). Throws
// InputError(folder, ...) when the folder is missing, has no image, or too few images show the board.
ChessboardCalibrationResult CalibrateChessboardFolder(const std::filesystem::path& folder,
                                                      const ChessboardCalibrationOptions& options);

// The image files CalibrateChessboardFolder() would use, in name order (throws InputError like it).
std::vector<std::filesystem::path> ListImageFiles(const std::filesystem::path& folder);

}  // namespace retrace
