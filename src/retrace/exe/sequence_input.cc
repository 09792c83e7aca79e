#include "retrace/exe/sequence_input.h"

#include <fmt/format.h>

#include "retrace/camera/camera_io.h"
#include "retrace/util/error.h"

#ifdef RETRACE_WITH_ROS
#include "retrace/ros/bag_sequence.h"
#endif

namespace retrace {

void AddBagOptions(CLI::App* command, BagInput* bag, bool with_camera_topic) {
  command->add_option("--topic", bag->topic,
                      "ROS bag: the image topic (sensor_msgs/Image mono8/bgr8/rgb8 or CompressedImage; default: the "
                      "bag's only image topic)");
  if (with_camera_topic) {
    command->add_option("--camera-topic", bag->camera_topic,
                        "ROS bag: the sensor_msgs/CameraInfo topic giving the camera when no --camera is given "
                        "(default: the image topic's sibling camera_info)");
  }
}

bool BuiltWithRos() {
#ifdef RETRACE_WITH_ROS
  return true;
#else
  return false;
#endif
}

std::unique_ptr<Sequence> OpenInputSequence(const std::filesystem::path& path, const BagInput& bag) {
  const bool is_bag = path.extension() == ".bag";
  if (!is_bag && (!bag.topic.empty() || !bag.camera_topic.empty())) {
    throw InputError(path.string(), "--topic and --camera-topic are for ROS bags (files named *.bag)");
  }
  if (!is_bag) return OpenSequence(path);
#ifdef RETRACE_WITH_ROS
  BagSequenceOptions options;
  options.topic = bag.topic;
  options.camera_topic = bag.camera_topic;
  return OpenBagSequence(path, options);
#else
  throw InputError(path.string(), "a ROS bag, but this retrace was built without ROS (install the ROS packages of "
                                  "scripts/install-deps and build again)");
#endif
}

std::unique_ptr<CameraModel> SequenceCamera(Sequence& sequence) {
#ifdef RETRACE_WITH_ROS
  if (const auto* bag = dynamic_cast<const BagSequence*>(&sequence)) {
    std::unique_ptr<CameraModel> camera = bag->camera();
    const cv::Size images = sequence.image_size();
    if (camera && !images.empty() && (camera->width() != images.width || camera->height() != images.height)) {
      throw InputError(fmt::format("{}: {}", bag->path().string(), bag->camera_topic()),
                       fmt::format("CameraInfo is {}x{} but the images on {} are {}x{}", camera->width(),
                                   camera->height(), bag->topic(), images.width, images.height));
    }
    return camera;
  }
#endif
  if (const auto file = sequence.calibration_file()) {
    return ReadCameraFile(*file, sequence.image_size(), sequence.calibration_camera());
  }
  return nullptr;
}

RecordSummary RecordSimulatedBag(Simulator* simulator, const std::filesystem::path& path,
                                 const RecordOptions& options) {
#ifdef RETRACE_WITH_ROS
  return RecordBag(simulator, path, options);
#else
  (void)simulator;
  (void)options;
  throw InputError(path.string(), "--bag: this retrace was built without ROS (install the ROS packages of "
                                  "scripts/install-deps and build again)");
#endif
}

}  // namespace retrace
