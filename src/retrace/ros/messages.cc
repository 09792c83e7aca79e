#include "retrace/ros/messages.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <Eigen/Geometry>
#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "retrace/camera/camera_io.h"
#include "retrace/camera/perspective_camera.h"
#include "retrace/image/image_utils.h"
#include "retrace/util/error.h"

namespace retrace {
namespace {

// Channels of an 8-bit encoding ImageMessageToGray accepts, 0 for any other.
int Channels(const std::string& encoding) {
  if (encoding == "mono8") return 1;
  if (encoding == "bgr8" || encoding == "rgb8") return 3;
  return 0;
}

// Doubles in YAML flow style with every digit, so that the camera parsed back is the message's exactly.
template <typename Container>
std::string YamlList(const Container& values) {
  std::string text = "[";
  for (const double v : values) text += fmt::format("{}{:.17g}", text.size() > 1 ? ", " : "", v);
  return text + "]";
}

}  // namespace

void CheckImageEncoding(const std::string& encoding, const std::string& source) {
  if (Channels(encoding) == 0) {
    throw InputError(source, fmt::format("image encoding '{}' is not supported (supported: mono8, bgr8, rgb8, or "
                                         "sensor_msgs/CompressedImage)",
                                         encoding));
  }
}

cv::Mat ImageMessageToGray(const sensor_msgs::Image& message, const std::string& source) {
  CheckImageEncoding(message.encoding, source);
  const int channels = Channels(message.encoding);
  const size_t row_bytes = static_cast<size_t>(message.width) * channels;
  if (message.width == 0 || message.height == 0 || message.step < row_bytes ||
      message.data.size() < static_cast<size_t>(message.step) * message.height) {
    throw InputError(source, fmt::format("malformed {} image message: {}x{} pixels, step {}, {} bytes of data",
                                         message.encoding, message.width, message.height, message.step,
                                         message.data.size()));
  }
  // A view of the message's rows (no copy), then converted into a new image.
  const cv::Mat view(static_cast<int>(message.height), static_cast<int>(message.width), CV_8UC(channels),
                     const_cast<uint8_t*>(message.data.data()), message.step);
  if (message.encoding == "rgb8") {
    cv::Mat gray;
    cv::cvtColor(view, gray, cv::COLOR_RGB2GRAY);
    return gray;
  }
  return channels == 1 ? view.clone() : ToGray8(view);
}

cv::Mat CompressedImageMessageToGray(const sensor_msgs::CompressedImage& message) {
  if (message.data.empty()) return cv::Mat();
  cv::Mat decoded;
  try {
    decoded = cv::imdecode(message.data, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception&) {
    decoded.release();
  }
  return ToGray8(decoded);
}

sensor_msgs::Image ImageToMessage(const cv::Mat& image, const ros::Time& stamp, const std::string& frame_id) {
  if (image.type() != CV_8UC1 && image.type() != CV_8UC3) {
    throw std::invalid_argument("ImageToMessage: only 8-bit gray or BGR images");
  }
  sensor_msgs::Image message;
  message.header.stamp = stamp;
  message.header.frame_id = frame_id;
  message.width = static_cast<uint32_t>(image.cols);
  message.height = static_cast<uint32_t>(image.rows);
  message.encoding = image.channels() == 1 ? "mono8" : "bgr8";
  message.is_bigendian = 0;
  message.step = static_cast<uint32_t>(image.cols * image.channels());
  message.data.resize(static_cast<size_t>(message.step) * message.height);
  for (int y = 0; y < image.rows; ++y) {
    std::copy_n(image.ptr<uint8_t>(y), message.step, message.data.data() + static_cast<size_t>(y) * message.step);
  }
  return message;
}

std::unique_ptr<CameraModel> CameraFromCameraInfo(const sensor_msgs::CameraInfo& info, const std::string& source) {
  if (std::all_of(info.K.begin(), info.K.end(), [](double v) { return v == 0.0; })) {
    throw InputError(source, "uncalibrated camera (CameraInfo K is all zeros); give a calibration file");
  }
  if (info.binning_x > 1 || info.binning_y > 1) {
    throw InputError(source, fmt::format("CameraInfo with binning {}x{} is not supported (the images are not the "
                                         "calibrated ones)",
                                         info.binning_x, info.binning_y));
  }
  const sensor_msgs::RegionOfInterest& roi = info.roi;
  if (roi.width != 0 && (roi.x_offset != 0 || roi.y_offset != 0 || roi.width != info.width ||
                         roi.height != info.height)) {
    throw InputError(source, "CameraInfo with a region of interest is not supported (the images are not the "
                             "calibrated ones)");
  }
  // The camera layer reads the numbers as it reads a `rostopic echo` dump of the message, with every check of a
  // calibration file (image size, focal lengths, distortion model and coefficients).
  std::string yaml = fmt::format("width: {}\nheight: {}\ndistortion_model: \"{}\"\nK: {}\n", info.width,
                                 info.height, info.distortion_model, YamlList(info.K));
  if (!info.D.empty()) yaml += fmt::format("D: {}\n", YamlList(info.D));
  return ParseCameraText(yaml, source);
}

sensor_msgs::CameraInfo CameraToCameraInfo(const CameraModel& camera, const ros::Time& stamp,
                                           const std::string& frame_id) {
  const auto* perspective = dynamic_cast<const PerspectiveCamera*>(&camera);
  if (perspective == nullptr) {
    throw InputError("", fmt::format("a {} camera has no sensor_msgs/CameraInfo distortion model (only perspective "
                                     "cameras can be written to a bag)",
                                     camera.model_name()));
  }
  sensor_msgs::CameraInfo info;
  info.header.stamp = stamp;
  info.header.frame_id = frame_id;
  info.width = static_cast<uint32_t>(camera.width());
  info.height = static_cast<uint32_t>(camera.height());
  info.distortion_model = "plumb_bob";
  const LensDistortion& d = perspective->distortion();
  info.D = {d.k1, d.k2, d.p1, d.p2, d.k3};
  const Matrix3d k = perspective->K();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      info.K[3 * r + c] = k(r, c);
      info.R[3 * r + c] = r == c ? 1.0 : 0.0;
      info.P[4 * r + c] = k(r, c);
    }
    info.P[4 * r + 3] = 0.0;
  }
  return info;
}

geometry_msgs::Pose RigidToPose(const Rigid3d& transform) {
  geometry_msgs::Pose pose;
  pose.position.x = transform.translation.x();
  pose.position.y = transform.translation.y();
  pose.position.z = transform.translation.z();
  const Eigen::Quaterniond q(transform.rotation);
  pose.orientation.w = q.w();
  pose.orientation.x = q.x();
  pose.orientation.y = q.y();
  pose.orientation.z = q.z();
  return pose;
}

ros::Time SecondsToRosTime(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0.0 || seconds > 4.0e9) {
    throw InputError("", fmt::format("time {} s cannot be a ROS time (0 .. 4e9 s)", seconds));
  }
  const double whole = std::floor(seconds);
  int64_t nanoseconds = std::llround((seconds - whole) * 1e9);
  int64_t secs = static_cast<int64_t>(whole);
  if (nanoseconds >= 1000000000) {
    nanoseconds -= 1000000000;
    ++secs;
  }
  return ros::Time(static_cast<uint32_t>(secs), static_cast<uint32_t>(nanoseconds));
}

}  // namespace retrace
