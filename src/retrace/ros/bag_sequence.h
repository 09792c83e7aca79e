#pragma once

// ROS 1 bags as image sequences, and simulated drives written as bags.
//
// A BagSequence reads the messages of one image topic (sensor_msgs/Image in mono8, bgr8 or rgb8, or
// sensor_msgs/CompressedImage) in the order the bag stores them (record time), as 8-bit gray frames:
//  - Frame::timestamp is the message's header stamp in seconds (the record time when the stamp is zero, as some
//    drivers leave it);
//  - Frame::name is "frame_NNNNNN", the position among the topic's messages;
//  - the camera comes from the first sensor_msgs/CameraInfo on the camera topic (messages.h maps its distortion
//    models to retrace's camera models).
// As for the other layouts (dataset/sequence.h), a frame that cannot be decoded (a damaged compressed image, a
// message that does not deserialize) is warned about, recorded in skipped() and passed over; a frame of another
// size than the first, or in an encoding retrace does not read, is an InputError naming the bag and the topic.
// A file that is not a bag, a topic the bag does not hold, or one that does not carry images are InputErrors from
// OpenBagSequence, each with a one-line message naming the bag.
//
// RecordBag writes a simulated drive as a bag: the frames (mono8, or bgr8 for a colour sensor), the camera as
// CameraInfo with every frame, and the ground-truth camera pose (world_from_cam in the simulator's world frame,
// sim/simulator.h: x right, y down, z forward — not REP 103's x forward, z up) as geometry_msgs/PoseStamped. Header
// stamps and record times are the frame times, except the first frame's 0, written as 1 ns (a zero stamp means
// "none" in ROS, and a bag holds no message at time 0).

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "retrace/camera/camera_model.h"
#include "retrace/dataset/sequence.h"
#include "retrace/sim/recording.h"
#include "retrace/sim/simulator.h"

namespace retrace {

struct BagSequenceOptions {
  // The image topic. Empty: the bag's only image topic (an error naming the candidates when it holds several).
  std::string topic;
  // The sensor_msgs/CameraInfo topic. Empty: the image topic's sibling camera_info (/cam/image_raw ->
  // /cam/camera_info; /cam/image_raw/compressed -> /cam/camera_info), used when present. A topic given here must
  // be in the bag.
  std::string camera_topic;
};

// The sibling camera_info topic of an image topic: the image topic's namespace + "camera_info" (a trailing
// "/compressed" of a compressed image transport removed first).
std::string SiblingCameraInfoTopic(const std::string& image_topic);

// True for paths OpenInputSequence (exe) hands to OpenBagSequence: files named *.bag.
bool IsBagPath(const std::filesystem::path& path);

class BagSequence : public Sequence {
 public:
  ~BagSequence() override;

  size_t size() const override;
  std::optional<Frame> Next() override;
  bool Read(size_t index, Frame* frame) override;
  void Rewind() override { cursor_ = 0; }
  std::string layout() const override { return "rosbag"; }
  std::filesystem::path path() const override { return path_; }

  // The image topic read and the CameraInfo topic used (empty when the bag holds none).
  const std::string& topic() const { return topic_; }
  const std::string& camera_topic() const { return camera_topic_; }
  // The camera of the first CameraInfo message on camera_topic(); null when there is none. Throws InputError
  // naming the bag and topic when that CameraInfo cannot be used (messages.h).
  std::unique_ptr<CameraModel> camera() const;

 private:
  friend std::unique_ptr<BagSequence> OpenBagSequence(const std::filesystem::path&, const BagSequenceOptions&);
  struct Data;
  BagSequence(std::filesystem::path path, std::unique_ptr<Data> data);

  std::filesystem::path path_;
  std::unique_ptr<Data> data_;
  std::string topic_;
  std::string camera_topic_;
  size_t cursor_ = 0;
};

// Opens the bag at `path` and indexes the messages of the image topic. Throws InputError naming the file when it is
// missing, not a ROS bag (or unindexed), or the topic is missing, carries no images, or is in an unsupported
// encoding (checked on its first message).
std::unique_ptr<BagSequence> OpenBagSequence(const std::filesystem::path& path,
                                             const BagSequenceOptions& options = {});

// Topics RecordBag writes.
struct BagTopics {
  std::string image = "/camera/image_raw";
  std::string camera_info = "/camera/camera_info";
  std::string pose = "/ground_truth/pose";
  // header.frame_id of the images and CameraInfo, and of the poses.
  std::string camera_frame = "camera";
  std::string world_frame = "world";
};

// Drives the simulator as RecordSequence does (sim/recording.h: to the route's end or the scenario's frame count)
// and writes the drive to the bag `path` (overwritten). options.progress is honoured; a contact sheet is not
// written. Throws InputError naming the file when it cannot be written, or for a camera without a CameraInfo model.
RecordSummary RecordBag(Simulator* simulator, const std::filesystem::path& path, const RecordOptions& options,
                        const BagTopics& topics = {});

}  // namespace retrace
