#pragma once

// Reading and writing camera calibration files.
//
// ReadCameraFile() recognises the formats users already have, by their content (not their file name):
//  - ROS camera_info YAML (image_width, image_height, camera_matrix {rows, cols, data}, distortion_model,
//    distortion_coefficients), also as a `rostopic echo` message dump (width, height, K, D, distortion_model);
//  - OpenCV FileStorage YAML (%YAML:1.0) or XML: camera_matrix / cameraMatrix (or M1 of a stereo file) as an
//    !!opencv-matrix, distortion_coefficients / distCoeffs / D (k1 k2 p1 p2 [k3]), image size from
//    image_width/image_height, imageSize/image_size [w, h] or width/height when present; an `xi` key makes it the
//    unified model as written by OpenCV's omnidir calibration sample;
//  - KITTI odometry calib.txt (lines "P0: <3x4 projection matrix>" to "P3: ..." for image_0 to image_3; P0 unless
//    `camera` names another); it has no image size;
//  - EuRoC / Kalibr sensor.yaml (resolution [w, h], intrinsics [fu fv cu cv], distortion_model radial-tangential;
//    camera_model omni with intrinsics [xi fu fv cu cv] for the unified model), also cam0 of a Kalibr camchain.yaml;
//  - retrace's own files written by WriteCameraFile(): ROS camera_info layout plus `camera_model: perspective |
//    unified | equirectangular` and `xi` for the unified model.
// When the file has no image size, `image_size` (the size of the images used with it) supplies it; when both exist
// they must agree. Distortion must be radial-tangential (plumb bob; rational_polynomial only with k4..k6 = 0).
//
// Every problem throws retrace::InputError(path, problem) with a one-line message: missing or unreadable file, not
// YAML, missing key (named), wrong matrix size, non-positive focal length, image size mismatch, unknown camera or
// distortion model.

#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include <opencv2/core/types.hpp>

#include "retrace/camera/camera_model.h"

namespace retrace {

// `camera`: which camera of a file that holds several (KITTI calib.txt: "P0" to "P3", Sequence::calibration_camera);
// empty for the first (P0); the formats that hold one camera ignore it. A name other than P0-P3 is an error.
std::unique_ptr<CameraModel> ReadCameraFile(const std::filesystem::path& path,
                                             std::optional<cv::Size> image_size = std::nullopt,
                                             const std::string& camera = "");

// ReadCameraFile() on text already in memory (e.g. the camera stored in a map database); `source` names it in
// errors, e.g. "map.db: cameras".
std::unique_ptr<CameraModel> ParseCameraText(const std::string& text, const std::string& source,
                                             std::optional<cv::Size> image_size = std::nullopt,
                                             const std::string& camera = "");

// Writes `camera` as YAML: a standard ROS camera_info file for the perspective model (plumb_bob distortion, also
// readable by ROS), the same layout with `camera_model` and `xi` for the unified model, and only the image size
// and `camera_model: equirectangular` for panoramas. Throws InputError when the file cannot be written.
void WriteCameraFile(const CameraModel& camera, const std::filesystem::path& path);

// The YAML text WriteCameraFile() writes (for storing a camera elsewhere, e.g. in a map database).
std::string CameraToYaml(const CameraModel& camera);

// Human-readable multi-line description of the model and its parameters (for the command line).
std::string DescribeCamera(const CameraModel& camera);

}  // namespace retrace
