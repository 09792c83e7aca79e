#pragma once

// retrace_node: repeat as a ROS 1 node. It localizes the frames of a camera in a taught map and steers the robot
// along the taught route (Segvic 2009 §6.3), as `retrace repeat` does for a recorded sequence.
//
// Subscribes (names relative to the node's namespace, remap them as usual, e.g. image:=/camera/image_raw):
//   image             sensor_msgs/Image (mono8, bgr8, rgb8), or with ~compressed
//   image/compressed  sensor_msgs/CompressedImage
//   camera_info       sensor_msgs/CameraInfo, only with ~use_camera_info (the first message is used)
// Publishes:
//   cmd_vel           geometry_msgs/Twist, one per processed frame: linear.x = ~speed while the frame is `tracking`,
//                     0 otherwise; angular.z = -w, w the steering of Segvic 2009 eq. (10) (FrameResult::steering,
//                     w = k mean(x_t - x*) over the current arc's features, k = ~steering_gain), 0 when not
//                     tracking or without a steering estimate. Sign convention of REP 103: positive angular.z turns
//                     left (counter-clockwise seen from above); w < 0 means the next key-image looks to the left of
//                     the current view, so the robot turns left. Units: rad/s for a steering gain in rad/s per unit
//                     of normalised image coordinate.
//   ~state            std_msgs/String, one JSON object per processed frame (see StateJson): frame, stamp, state,
//                     arc, node_from, node_to, confidence, position_on_arc, steering, tracked, transition, ms,
//                     dropped. A JSON string in a standard message rather than a custom message type: custom
//                     messages need catkin's message generation, which a plain CMake build from Debian packages
//                     does not have; any ROS tool (rostopic echo, rosbag, Python's json) reads it.
//   /diagnostics      diagnostic_msgs/DiagnosticArray every ~diagnostics_period seconds, status "<node name>: repeat"
//                     (e.g. "/retrace_node: repeat"), hardware_id the map: OK while tracking, WARN
//                     when lost or relocalizing or when no frame arrived for 2 periods, ERROR after a frame that
//                     could not be used (e.g. another image size); values: state, arc, confidence, frames
//                     received / processed / dropped, mean processing time.
//
// Keeping up with the camera: frames are localized in a worker thread, always the newest frame received; a frame
// that arrives while another waits replaces it (the waiting one is dropped and counted). The subscriptions have a
// queue of 1. With ~process_every_frame (tests, offline bags played slowly) every frame is queued and processed in
// order instead.

#include <condition_variable>
#include <deque>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include <ros/ros.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>

#include "retrace/camera/camera_model.h"
#include "retrace/repeat/localizer.h"
#include "retrace/repeat/map_loading.h"

namespace retrace {

struct RepeatNodeOptions {
  // ~map: the map written by `retrace teach` (required).
  std::filesystem::path map;
  // ~camera: a calibration file of the camera. Default: the camera stored in the map. A camera given here or by
  // camera_info must image the same rays as the map's (within 1 px at the key-images' width), as in `retrace repeat`.
  std::filesystem::path camera;
  // ~use_camera_info: take the camera from the first sensor_msgs/CameraInfo on camera_info (waits for it).
  bool use_camera_info = false;
  // ~speed: linear.x of cmd_vel while tracking, m/s.
  double speed = 0.5;
  // ~compressed: subscribe image/compressed (sensor_msgs/CompressedImage) instead of image.
  bool compressed = false;
  // ~process_every_frame: queue and process every frame instead of the newest one (see the top of this file).
  bool process_every_frame = false;
  // ~start_arc: bootstrap on this arc (Segvic 2009 §3.3); -1: found by retrieval.
  arc_t start_arc = kInvalidArcId;
  // ~diagnostics_period: seconds between /diagnostics messages.
  double diagnostics_period = 1.0;
  // The localizer's main options, ~max_residual, ~max_sigma_p, ~steering_gain, ~max_bad_frames, ~min_confidence,
  // ~retrieval_shortlist, ~start_retrieval_shortlist, ~max_cached_key_images, as `retrace repeat`'s options of the
  // same names; defaults: LocalizerOptions'. The map's stored tracking settings (reference width, smoothing) are
  // applied on top.
  LocalizerOptions localizer;

  bool Check(std::string* error) const;
};

// The node's private parameters (~name, documented in RepeatNodeOptions). Throws InputError naming the parameter
// for a missing map or an invalid value.
RepeatNodeOptions ReadRepeatNodeOptions(const ros::NodeHandle& private_node);

// The state message's JSON for one processed frame; `stamp` is the frame's header stamp in seconds and `dropped`
// the frames dropped so far.
std::string StateJson(const FrameResult& result, double stamp, size_t dropped);

class RepeatNode {
 public:
  // Loads the map and the camera, advertises and subscribes, starts the worker. Throws InputError for a map or
  // camera that cannot be used.
  RepeatNode(const ros::NodeHandle& node, const ros::NodeHandle& private_node, const RepeatNodeOptions& options);
  // Stops the worker (the frame being processed is finished first).
  ~RepeatNode();

  RepeatNode(const RepeatNode&) = delete;
  RepeatNode& operator=(const RepeatNode&) = delete;

 private:
  // A received frame waiting for the worker.
  struct Pending {
    ros::Time stamp;
    cv::Mat gray;
  };

  void OnImage(const sensor_msgs::ImageConstPtr& message);
  void OnCompressedImage(const sensor_msgs::CompressedImageConstPtr& message);
  void Enqueue(const ros::Time& stamp, cv::Mat gray);
  void Work();
  void Process(Pending pending);
  void PublishStop();
  void PublishDiagnostics(const ros::TimerEvent& event);

  RepeatNodeOptions options_;
  ros::NodeHandle node_;
  ros::NodeHandle private_node_;
  MapForLocalizer loaded_;
  std::unique_ptr<CameraModel> camera_;  // at the key-images' width
  std::unique_ptr<Localizer> localizer_;

  ros::Publisher cmd_vel_;
  ros::Publisher state_;
  ros::Publisher diagnostics_;
  ros::Subscriber image_subscriber_;
  ros::Timer diagnostics_timer_;

  std::mutex mutex_;  // guards everything below
  std::condition_variable wake_;
  std::deque<Pending> pending_;
  bool stopping_ = false;
  size_t received_ = 0;
  size_t processed_ = 0;
  size_t dropped_ = 0;
  size_t unusable_ = 0;
  std::string last_error_;
  std::optional<FrameResult> last_result_;
  double seconds_processing_ = 0.0;
  ros::WallTime last_received_;
  std::thread worker_;
};

}  // namespace retrace
