#include "retrace/ros/bag_sequence.h"

#include <algorithm>
#include <chrono>
#include <map>

#include <fmt/format.h>
#include <geometry_msgs/PoseStamped.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>

#include "retrace/ros/messages.h"
#include "retrace/util/error.h"
#include "retrace/util/progress.h"

namespace retrace {
namespace fs = std::filesystem;

namespace {

constexpr const char* kImageType = "sensor_msgs/Image";
constexpr const char* kCompressedImageType = "sensor_msgs/CompressedImage";
constexpr const char* kCameraInfoType = "sensor_msgs/CameraInfo";

// Topic names as the bag stores them: absolute.
std::string Absolute(const std::string& topic) { return topic.empty() || topic[0] == '/' ? topic : "/" + topic; }

std::string JoinTopics(const std::vector<std::string>& topics) {
  std::string text;
  for (const std::string& t : topics) text += (text.empty() ? "" : ", ") + t;
  return text.empty() ? "none" : text;
}

}  // namespace

struct BagSequence::Data {
  rosbag::Bag bag;
  // The image topic's messages in record order (an index into the bag; the data is read by Read).
  std::vector<rosbag::MessageInstance> images;
  bool compressed = false;
  std::optional<sensor_msgs::CameraInfo> camera_info;
};

std::string SiblingCameraInfoTopic(const std::string& image_topic) {
  std::string topic = image_topic;
  const std::string compressed = "/compressed";
  if (topic.size() > compressed.size() && topic.compare(topic.size() - compressed.size(), compressed.size(),
                                                        compressed) == 0) {
    topic.resize(topic.size() - compressed.size());
  }
  const size_t slash = topic.rfind('/');
  return (slash == std::string::npos ? std::string() : topic.substr(0, slash)) + "/camera_info";
}

bool IsBagPath(const fs::path& path) { return path.extension() == ".bag"; }

BagSequence::BagSequence(fs::path path, std::unique_ptr<Data> data) : path_(std::move(path)), data_(std::move(data)) {}

BagSequence::~BagSequence() = default;

size_t BagSequence::size() const { return data_->images.size(); }

std::optional<Frame> BagSequence::Next() {
  while (cursor_ < data_->images.size()) {
    Frame frame;
    if (Read(cursor_++, &frame)) return frame;
  }
  return std::nullopt;
}

bool BagSequence::Read(size_t index, Frame* frame) {
  if (index >= data_->images.size()) return false;
  const rosbag::MessageInstance& message = data_->images[index];
  const std::string name = fmt::format("frame_{:06d}", index);
  const std::string source = fmt::format("{}: {} message {}", path_.string(), topic_, index);
  cv::Mat image;
  ros::Time stamp;
  try {
    if (data_->compressed) {
      const auto compressed = message.instantiate<sensor_msgs::CompressedImage>();
      if (compressed) {
        image = CompressedImageMessageToGray(*compressed);
        stamp = compressed->header.stamp;
      }
    } else if (const auto raw = message.instantiate<sensor_msgs::Image>()) {
      // An encoding retrace does not read is the whole topic's problem, not one damaged frame.
      CheckImageEncoding(raw->encoding, path_.string() + ": " + topic_);
      try {
        image = ImageMessageToGray(*raw, source);
      } catch (const InputError& e) {
        ReportUnreadable(name, source, e.problem());
        return false;
      }
      stamp = raw->header.stamp;
    }
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {  // rosbag::BagException, ros::serialization exceptions: a damaged message
    ReportUnreadable(name, source, fmt::format("cannot be read ({})", e.what()));
    return false;
  }
  if (image.empty()) {
    ReportUnreadable(name, source, "cannot be decoded as an image");
    return false;
  }
  CheckFrameSize(image.size(), source);
  frame->index = index;
  frame->source_index = index;
  frame->name = name;
  frame->timestamp = stamp.isZero() ? message.getTime().toSec() : stamp.toSec();
  frame->image = std::move(image);
  return true;
}

std::unique_ptr<CameraModel> BagSequence::camera() const {
  if (!data_->camera_info) return nullptr;
  return CameraFromCameraInfo(*data_->camera_info, fmt::format("{}: {}", path_.string(), camera_topic_));
}

std::unique_ptr<BagSequence> OpenBagSequence(const fs::path& path, const BagSequenceOptions& options) {
  const std::string file = path.string();
  std::error_code ec;
  CheckInput(fs::exists(path, ec), file, "no such file");
  CheckInput(fs::is_regular_file(path, ec), file, "not a file (a ROS bag is one .bag file)");
  auto data = std::make_unique<BagSequence::Data>();
  try {
    data->bag.open(file, rosbag::bagmode::Read);
  } catch (const std::exception& e) {
    throw InputError(file, fmt::format("not a readable ROS bag ({})", e.what()));
  }

  // Every topic and its message type.
  std::map<std::string, std::string> types;
  std::vector<std::string> image_topics;
  {
    rosbag::View all(data->bag);
    for (const rosbag::ConnectionInfo* connection : all.getConnections()) {
      if (!types.emplace(connection->topic, connection->datatype).second) continue;
      if (connection->datatype == kImageType || connection->datatype == kCompressedImageType) {
        image_topics.push_back(connection->topic);
      }
    }
  }
  std::sort(image_topics.begin(), image_topics.end());

  std::string topic = Absolute(options.topic);
  if (topic.empty()) {
    if (image_topics.size() != 1) {
      throw InputError(file, image_topics.empty()
                                 ? fmt::format("holds no image topic (sensor_msgs/Image or CompressedImage)")
                                 : fmt::format("holds {} image topics ({}): choose one with --topic",
                                               image_topics.size(), JoinTopics(image_topics)));
    }
    topic = image_topics.front();
  }
  const auto type = types.find(topic);
  if (type == types.end()) {
    throw InputError(file, fmt::format("no topic {} in the bag (image topics: {})", topic, JoinTopics(image_topics)));
  }
  if (type->second != kImageType && type->second != kCompressedImageType) {
    throw InputError(file, fmt::format("topic {} carries {}, not {} or {}", topic, type->second, kImageType,
                                       kCompressedImageType));
  }
  data->compressed = type->second == kCompressedImageType;
  try {
    rosbag::View view(data->bag, rosbag::TopicQuery(topic));
    for (const rosbag::MessageInstance& message : view) data->images.push_back(message);
  } catch (const std::exception& e) {
    throw InputError(file, fmt::format("cannot read the index of {} ({})", topic, e.what()));
  }
  CheckInput(!data->images.empty(), file, fmt::format("topic {} has no messages", topic));
  if (!data->compressed) {
    // The encoding, from the first message: a topic retrace cannot read is refused before any work is done.
    boost::shared_ptr<sensor_msgs::Image> first;
    try {
      first = data->images.front().instantiate<sensor_msgs::Image>();
    } catch (const std::exception&) {
      first.reset();  // a damaged first message: Read reports it as an unreadable frame
    }
    if (first) CheckImageEncoding(first->encoding, file + ": " + topic);
  }

  // The camera: the first CameraInfo on the given topic, else on the image topic's sibling when the bag has it.
  std::string camera_topic = Absolute(options.camera_topic);
  if (!camera_topic.empty()) {
    const auto camera_type = types.find(camera_topic);
    if (camera_type == types.end()) throw InputError(file, fmt::format("no topic {} in the bag", camera_topic));
    if (camera_type->second != kCameraInfoType) {
      throw InputError(file, fmt::format("topic {} carries {}, not {}", camera_topic, camera_type->second,
                                         kCameraInfoType));
    }
  } else {
    camera_topic = SiblingCameraInfoTopic(topic);
    const auto camera_type = types.find(camera_topic);
    if (camera_type == types.end() || camera_type->second != kCameraInfoType) camera_topic.clear();
  }
  if (!camera_topic.empty()) {
    try {
      rosbag::View view(data->bag, rosbag::TopicQuery(camera_topic));
      for (const rosbag::MessageInstance& message : view) {
        if (const auto info = message.instantiate<sensor_msgs::CameraInfo>()) {
          data->camera_info = *info;
          break;
        }
      }
    } catch (const std::exception& e) {
      throw InputError(file, fmt::format("cannot read {} ({})", camera_topic, e.what()));
    }
    if (!data->camera_info) throw InputError(file, fmt::format("no readable CameraInfo on {}", camera_topic));
  }

  std::unique_ptr<BagSequence> sequence(new BagSequence(path, std::move(data)));
  sequence->topic_ = topic;
  sequence->camera_topic_ = camera_topic;
  return sequence;
}

RecordSummary RecordBag(Simulator* simulator, const fs::path& path, const RecordOptions& options,
                        const BagTopics& topics) {
  const auto start = std::chrono::steady_clock::now();
  sensor_msgs::CameraInfo info;
  try {
    info = CameraToCameraInfo(simulator->camera(), ros::Time(), topics.camera_frame);
  } catch (const InputError& e) {
    throw InputError(path.string(), e.problem());
  }
  rosbag::Bag bag;
  try {
    bag.open(path.string(), rosbag::bagmode::Write);
  } catch (const std::exception& e) {
    throw InputError(path.string(), fmt::format("cannot be written ({})", e.what()));
  }

  RecordSummary summary;
  summary.route_length_m = simulator->route().length();
  ProgressBar progress("render", static_cast<size_t>(simulator->ExpectedFrames()), options.progress);
  SimFrame frame;
  try {
    while (simulator->NextFrame(&frame)) {
      // A zero stamp means "none" in ROS and a bag holds no message at time 0: the first frame is at 1 ns.
      const ros::Time stamp = std::max(SecondsToRosTime(frame.timestamp), ros::TIME_MIN);
      bag.write(topics.image, stamp, ImageToMessage(frame.image, stamp, topics.camera_frame));
      info.header.stamp = stamp;
      bag.write(topics.camera_info, stamp, info);
      geometry_msgs::PoseStamped pose;
      pose.header.stamp = stamp;
      pose.header.frame_id = topics.world_frame;
      pose.pose = RigidToPose(frame.world_from_cam);
      bag.write(topics.pose, stamp, pose);
      summary.driven_m = frame.progress;
      ++summary.frames;
      progress.Advance(1);
    }
    bag.close();
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {  // rosbag::BagException: disk full, ...
    throw InputError(path.string(), fmt::format("write failed ({})", e.what()));
  }
  progress.Finish();
  summary.frames_requested = simulator->scenario().num_frames;
  summary.stopped_at_route_end = summary.frames_requested > 0 && summary.frames < summary.frames_requested;
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace retrace
