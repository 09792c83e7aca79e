#include "retrace/ros/repeat_node.h"

#include <chrono>
#include <cmath>
#include <utility>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <fmt/format.h>
#include <geometry_msgs/Twist.h>
#include <nlohmann/json.hpp>
#include <ros/topic.h>
#include <sensor_msgs/CameraInfo.h>
#include <std_msgs/String.h>

#include "retrace/camera/camera_checks.h"
#include "retrace/camera/camera_io.h"
#include "retrace/image/image_utils.h"
#include "retrace/ros/messages.h"
#include "retrace/util/error.h"

namespace retrace {
namespace {

// Two calibrations that image the same rays within this distance at the key-images' resolution are one camera (as
// in `retrace repeat`).
constexpr double kSameCameraPx = 1.0;
// Frames queued with ~process_every_frame before the oldest is dropped after all (a bound on memory).
constexpr size_t kMaxQueuedFrames = 10000;

template <typename T>
void ReadParameter(const ros::NodeHandle& node, const std::string& name, T* value) {
  if (!node.hasParam(name)) return;
  if (!node.getParam(name, *value)) {
    throw InputError(node.resolveName(name), "parameter has the wrong type");
  }
}

// The camera the frames are localized with, at the key-images' width: the map's, or the one given (a file or
// CameraInfo) when it images the same rays.
std::unique_ptr<CameraModel> NodeCamera(const MapForLocalizer& loaded, std::unique_ptr<CameraModel> given,
                                        const std::string& given_source, const std::string& map_source) {
  const int key_width = loaded.key_image_size.width;
  if (!given) {
    if (!loaded.camera) throw InputError(map_source, "the map stores no camera; set ~camera or ~use_camera_info");
    return loaded.camera->Clone();
  }
  std::unique_ptr<CameraModel> camera =
      given->width() == key_width ? std::move(given) : given->Scaled(static_cast<double>(key_width) / given->width());
  if (loaded.camera) {
    const double difference = CameraProjectionDifferencePx(*loaded.camera, *camera);
    if (!(difference <= kSameCameraPx) || camera->model_name() != loaded.camera->model_name() ||
        camera->height() != loaded.camera->height()) {
      throw InputError(given_source,
                       fmt::format("differs from the map's camera ({} at the map's {} px width): {} {} vs the map's "
                                   "{} {}",
                                   std::isfinite(difference) ? fmt::format("{:.1f} px apart", difference)
                                                             : "rays not imaged",
                                   key_width, camera->model_name(), DescribeCameraIntrinsics(*camera),
                                   loaded.camera->model_name(), DescribeCameraIntrinsics(*loaded.camera)));
    }
  }
  return camera;
}

}  // namespace

bool RepeatNodeOptions::Check(std::string* error) const {
  const auto fail = [&](const std::string& message) {
    if (error) *error = message;
    return false;
  };
  if (map.empty()) return fail("~map: the map file is required (e.g. _map:=route.db)");
  if (!camera.empty() && use_camera_info) return fail("~camera and ~use_camera_info: give one of them");
  if (!(std::isfinite(speed) && speed >= 0.0 && speed <= 50.0)) return fail("~speed: must be in [0, 50] m/s");
  if (!(diagnostics_period > 0.0 && diagnostics_period <= 3600.0)) {
    return fail("~diagnostics_period: must be in (0, 3600] s");
  }
  if (start_arc < kInvalidArcId) return fail("~start_arc: an arc id, or -1");
  return localizer.Check(error);
}

RepeatNodeOptions ReadRepeatNodeOptions(const ros::NodeHandle& private_node) {
  RepeatNodeOptions options;
  std::string text;
  if (private_node.getParam("map", text)) options.map = text;
  text.clear();
  if (private_node.getParam("camera", text)) options.camera = text;
  ReadParameter(private_node, "use_camera_info", &options.use_camera_info);
  ReadParameter(private_node, "speed", &options.speed);
  ReadParameter(private_node, "compressed", &options.compressed);
  ReadParameter(private_node, "process_every_frame", &options.process_every_frame);
  int start_arc = -1;
  ReadParameter(private_node, "start_arc", &start_arc);
  options.start_arc = start_arc < 0 ? kInvalidArcId : start_arc;
  ReadParameter(private_node, "diagnostics_period", &options.diagnostics_period);
  LocalizerOptions& localizer = options.localizer;
  ReadParameter(private_node, "max_residual", &localizer.max_residual);
  ReadParameter(private_node, "max_sigma_p", &localizer.max_sigma_p_px);
  ReadParameter(private_node, "steering_gain", &localizer.steering_gain);
  ReadParameter(private_node, "max_bad_frames", &localizer.max_bad_frames);
  ReadParameter(private_node, "min_confidence", &localizer.belief.min_confidence);
  ReadParameter(private_node, "retrieval_shortlist", &localizer.retrieval_shortlist);
  ReadParameter(private_node, "start_retrieval_shortlist", &localizer.start_retrieval_shortlist);
  ReadParameter(private_node, "max_cached_key_images", &localizer.max_cached_key_images);
  std::string error;
  if (!options.Check(&error)) throw InputError(private_node.getNamespace(), error);
  return options;
}

std::string StateJson(const FrameResult& result, double stamp, size_t dropped) {
  const bool tracking = result.state == LocalizerState::kTracking;
  nlohmann::json state = {
      {"frame", result.frame_index},
      {"stamp", stamp},
      {"state", LocalizerStateName(result.state)},
      {"arc", result.arc},
      {"node_from", result.node_from},
      {"node_to", result.node_to},
      {"confidence", result.confidence},
      {"position_on_arc", nullptr},
      {"steering", nullptr},
      {"tracked", result.tracked},
      {"transition", result.transition},
      {"bootstrapped", result.bootstrapped},
      {"ms", 1000.0 * result.seconds},
      {"dropped", dropped},
  };
  if (tracking && result.position_valid) state["position_on_arc"] = result.position_on_arc;
  if (result.steering_valid) state["steering"] = result.steering;
  return state.dump();
}

RepeatNode::RepeatNode(const ros::NodeHandle& node, const ros::NodeHandle& private_node,
                       const RepeatNodeOptions& options)
    : options_(options), node_(node), private_node_(private_node) {
  loaded_ = LoadMapForLocalizer(options_.map, options_.localizer);
  std::unique_ptr<CameraModel> given;
  std::string given_source;
  if (!options_.camera.empty()) {
    given = ReadCameraFile(options_.camera);
    given_source = options_.camera.string();
  } else if (options_.use_camera_info) {
    given_source = node_.resolveName("camera_info");
    ROS_INFO("retrace_node: waiting for the camera on %s", given_source.c_str());
    const auto info = ros::topic::waitForMessage<sensor_msgs::CameraInfo>("camera_info", node_);
    if (!info) throw InputError(given_source, "no CameraInfo received (the node was shut down)");
    given = CameraFromCameraInfo(*info, given_source);
  }
  camera_ = NodeCamera(loaded_, std::move(given), given_source, options_.map.string());
  localizer_ = std::make_unique<Localizer>(std::move(loaded_.map), *camera_, loaded_.options);
  if (options_.start_arc != kInvalidArcId) localizer_->SetStartArc(options_.start_arc);

  cmd_vel_ = node_.advertise<geometry_msgs::Twist>("cmd_vel", 10);
  state_ = private_node_.advertise<std_msgs::String>("state", 100);
  diagnostics_ = node_.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 10);
  // Queue 1: the transport keeps only the newest frame; every frame when they are all to be processed.
  const uint32_t queue = options_.process_every_frame ? 1000 : 1;
  if (options_.compressed) {
    image_subscriber_ = node_.subscribe("image/compressed", queue, &RepeatNode::OnCompressedImage, this);
  } else {
    image_subscriber_ = node_.subscribe("image", queue, &RepeatNode::OnImage, this);
  }
  diagnostics_timer_ =
      node_.createTimer(ros::Duration(options_.diagnostics_period), &RepeatNode::PublishDiagnostics, this);
  last_received_ = ros::WallTime::now();
  worker_ = std::thread(&RepeatNode::Work, this);
  ROS_INFO("retrace_node: ready: map %s (%zu key-images, %zu arcs), camera %s %dx%d, listening on %s",
           options_.map.string().c_str(), localizer_->map().nodes().size(), localizer_->map().arcs().size(),
           camera_->model_name().c_str(), camera_->width(), camera_->height(),
           image_subscriber_.getTopic().c_str());
}

RepeatNode::~RepeatNode() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (worker_.joinable()) worker_.join();
}

void RepeatNode::OnImage(const sensor_msgs::ImageConstPtr& message) {
  cv::Mat gray;
  try {
    gray = ImageMessageToGray(*message, image_subscriber_.getTopic());
  } catch (const InputError& e) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++received_;
    ++unusable_;
    last_error_ = e.what();
    ROS_ERROR_THROTTLE(5.0, "retrace_node: %s", e.what());
    return;
  }
  Enqueue(message->header.stamp, std::move(gray));
}

void RepeatNode::OnCompressedImage(const sensor_msgs::CompressedImageConstPtr& message) {
  cv::Mat gray = CompressedImageMessageToGray(*message);
  if (gray.empty()) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++received_;
    ++unusable_;
    last_error_ = image_subscriber_.getTopic() + ": a compressed image that cannot be decoded";
    ROS_ERROR_THROTTLE(5.0, "retrace_node: %s", last_error_.c_str());
    return;
  }
  Enqueue(message->header.stamp, std::move(gray));
}

void RepeatNode::Enqueue(const ros::Time& stamp, cv::Mat gray) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ++received_;
    last_received_ = ros::WallTime::now();
    // A stale frame still waiting is replaced by this newer one (or, processing every frame, only beyond a bound).
    const size_t keep = options_.process_every_frame ? kMaxQueuedFrames - 1 : 0;
    while (pending_.size() > keep) {
      pending_.pop_front();
      ++dropped_;
    }
    pending_.push_back({stamp.isZero() ? ros::Time::now() : stamp, std::move(gray)});
  }
  wake_.notify_one();
}

void RepeatNode::Work() {
  while (true) {
    Pending pending;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [&] { return stopping_ || !pending_.empty(); });
      if (stopping_) return;
      pending = std::move(pending_.front());
      pending_.pop_front();
    }
    Process(std::move(pending));
  }
}

void RepeatNode::Process(Pending pending) {
  Frame frame;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    frame.index = frame.source_index = processed_;
  }
  frame.name = fmt::format("frame_{:06d}", frame.index);
  frame.timestamp = pending.stamp.toSec();
  frame.image = std::move(pending.gray);
  // Frames of the camera's shape at another resolution are resized to the key-images' width, as repeat does.
  if (frame.image.cols != camera_->width()) {
    cv::Mat resized;
    ResizeToWidth(frame.image, camera_->width(), &resized);
    frame.image = resized;
  }
  FrameResult result;
  try {
    result = localizer_->ProcessFrame(frame);
  } catch (const InputError& e) {  // a frame the camera does not describe (another image size)
    const std::string error = fmt::format("{}: {}", image_subscriber_.getTopic(), e.what());
    {
      std::lock_guard<std::mutex> lock(mutex_);
      ++unusable_;
      last_error_ = error;
    }
    ROS_ERROR_THROTTLE(5.0, "retrace_node: %s", error.c_str());
    PublishStop();
    return;
  }
  size_t dropped = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ++processed_;
    seconds_processing_ += result.seconds;
    dropped = dropped_;
  }

  const bool tracking = result.state == LocalizerState::kTracking;
  geometry_msgs::Twist twist;
  twist.linear.x = tracking ? options_.speed : 0.0;
  twist.angular.z = tracking && result.steering_valid ? -result.steering : 0.0;
  cmd_vel_.publish(twist);
  std_msgs::String state;
  state.data = StateJson(result, frame.timestamp, dropped);
  state_.publish(state);

  result.marks.clear();
  std::lock_guard<std::mutex> lock(mutex_);
  last_result_ = std::move(result);
}

void RepeatNode::PublishStop() { cmd_vel_.publish(geometry_msgs::Twist()); }

void RepeatNode::PublishDiagnostics(const ros::TimerEvent&) {
  diagnostic_msgs::DiagnosticStatus status;
  status.name = ros::this_node::getName() + ": repeat";  // e.g. "/retrace_node: repeat"
  status.hardware_id = options_.map.string();
  const auto value = [&](const std::string& key, const std::string& text) {
    diagnostic_msgs::KeyValue entry;
    entry.key = key;
    entry.value = text;
    status.values.push_back(entry);
  };
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const double silent = (ros::WallTime::now() - last_received_).toSec();
    // Frames received and not yet processed, dropped or refused: queued (process_every_frame) or being localized.
    // The camera is silent only when none is left; until then the node is busy, not starved.
    const bool frames_waiting = received_ > processed_ + dropped_ + unusable_;
    if (!last_error_.empty()) {
      status.level = diagnostic_msgs::DiagnosticStatus::ERROR;
      status.message = last_error_;
    } else if (silent > 2.0 * options_.diagnostics_period && !frames_waiting) {
      status.level = diagnostic_msgs::DiagnosticStatus::WARN;
      status.message = fmt::format("no frame for {:.1f} s on {}", silent, image_subscriber_.getTopic());
    } else if (!last_result_) {
      status.level = diagnostic_msgs::DiagnosticStatus::WARN;
      status.message = "waiting for the first frame";
    } else if (last_result_->state != LocalizerState::kTracking) {
      status.level = diagnostic_msgs::DiagnosticStatus::WARN;
      status.message = LocalizerStateName(last_result_->state);
    } else {
      status.level = diagnostic_msgs::DiagnosticStatus::OK;
      status.message = fmt::format("tracking on arc {}", last_result_->arc);
    }
    value("state", last_result_ ? LocalizerStateName(last_result_->state) : "none");
    value("arc", last_result_ ? std::to_string(last_result_->arc) : "-1");
    value("confidence", last_result_ ? fmt::format("{:.4f}", last_result_->confidence) : "0");
    value("frames received", std::to_string(received_));
    value("frames processed", std::to_string(processed_));
    value("frames dropped", std::to_string(dropped_));
    value("frames unusable", std::to_string(unusable_));
    value("mean processing ms", processed_ > 0 ? fmt::format("{:.2f}", 1000.0 * seconds_processing_ / processed_)
                                               : "0");
    last_error_.clear();  // an error is reported once, in the period it happened
  }
  diagnostic_msgs::DiagnosticArray array;
  array.header.stamp = ros::Time::now();
  array.status.push_back(status);
  diagnostics_.publish(array);
}

}  // namespace retrace
