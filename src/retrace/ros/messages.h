#pragma once

// Conversions between ROS 1 messages and retrace's types: images (sensor_msgs/Image, sensor_msgs/CompressedImage),
// cameras (sensor_msgs/CameraInfo) and poses (geometry_msgs/Pose).
//
// Images: retrace works on 8-bit gray frames. Raw images in the encodings mono8, bgr8 and rgb8 are converted as an
// image file of the same pixels would be (image/image_utils.h ToGray8: colour through BT.601 weights), compressed
// images are decoded by their content (PNG, JPEG, ... whatever cv::imdecode reads) and converted the same way.
//
// Cameras: CameraInfo's distortion models map to retrace's camera models as a calibration file with the same
// numbers would (camera/camera_io.h): plumb_bob, and rational_polynomial with k4..k6 = 0, are the perspective model
// with radial-tangential distortion; an empty model with no coefficients is a perspective camera without
// distortion. equidistant (fisheye) and every other model have no retrace counterpart and are refused, as are an
// uncalibrated CameraInfo (K all zeros) and binning or a region of interest (the images would not be the
// calibrated ones). Only perspective cameras are written as CameraInfo (unified and equirectangular cameras have no
// standard CameraInfo model).
//
// Every problem throws InputError(source, problem) with one line, `source` naming the bag and topic.

#include <memory>
#include <string>

#include <geometry_msgs/Pose.h>
#include <opencv2/core.hpp>
#include <ros/time.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>

#include "retrace/camera/camera_model.h"
#include "retrace/util/types.h"

namespace retrace {

// Throws InputError naming `source` unless ImageMessageToGray reads images in `encoding` (mono8, bgr8, rgb8).
void CheckImageEncoding(const std::string& encoding, const std::string& source);

// The message's pixels as an 8-bit gray image (a copy). Throws InputError naming `source` for an unsupported
// encoding or a message whose data does not hold width x height pixels at its step.
cv::Mat ImageMessageToGray(const sensor_msgs::Image& message, const std::string& source);

// The decoded image as 8-bit gray; an empty Mat when the data cannot be decoded (a damaged frame, reported by the
// caller like an unreadable image file).
cv::Mat CompressedImageMessageToGray(const sensor_msgs::CompressedImage& message);

// An 8-bit gray (mono8) or BGR (bgr8) image as a message with the given header fields. Throws std::invalid_argument
// for any other pixel type (a programming error, not input).
sensor_msgs::Image ImageToMessage(const cv::Mat& image, const ros::Time& stamp, const std::string& frame_id);

// The camera a CameraInfo message describes (see the top of this file). Throws InputError naming `source`.
std::unique_ptr<CameraModel> CameraFromCameraInfo(const sensor_msgs::CameraInfo& info, const std::string& source);

// A perspective camera as CameraInfo: plumb_bob distortion (k1 k2 p1 p2 k3), K, R = I, P = [K | 0]. Throws
// InputError for other camera models.
sensor_msgs::CameraInfo CameraToCameraInfo(const CameraModel& camera, const ros::Time& stamp,
                                           const std::string& frame_id);

// A rigid transform as a pose message (position = translation, orientation = the rotation's unit quaternion).
geometry_msgs::Pose RigidToPose(const Rigid3d& transform);

// Seconds as a ROS time (rounded to the nanosecond), and back. Throws InputError for a negative or non-finite time.
ros::Time SecondsToRosTime(double seconds);

}  // namespace retrace
