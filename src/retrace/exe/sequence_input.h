#pragma once

// The sequences teach, repeat and sequence-info read: OpenSequence's layouts (dataset/sequence.h), or a ROS bag
// (a file named *.bag, ros/bag_sequence.h) with the image topic to read (--topic) and the CameraInfo topic that
// gives the camera (--camera-topic). A retrace built without ROS refuses a bag with a one-line error saying so.

#include <filesystem>
#include <memory>
#include <string>

#include <CLI/CLI.hpp>

#include "retrace/camera/camera_model.h"
#include "retrace/dataset/sequence.h"
#include "retrace/sim/recording.h"
#include "retrace/sim/simulator.h"

namespace retrace {

// The bag options of a command (unused for other sequences).
struct BagInput {
  std::string topic;
  std::string camera_topic;
};

// Adds --topic (and, when `with_camera_topic`, --camera-topic) to `command`.
void AddBagOptions(CLI::App* command, BagInput* bag, bool with_camera_topic);

// True when this retrace was built with the ROS layer.
bool BuiltWithRos();

// OpenSequence(path), or the bag's image topic when `path` is a bag. Throws InputError naming the file.
std::unique_ptr<Sequence> OpenInputSequence(const std::filesystem::path& path, const BagInput& bag = {});

// The camera that comes with the sequence when no --camera is given: its calibration file (read for its image
// size), or the CameraInfo of a bag. Null when it has none.
std::unique_ptr<CameraModel> SequenceCamera(Sequence& sequence);

// `sim render --bag`: the drive written as a ROS bag (ros/bag_sequence.h RecordBag). Throws InputError when this
// retrace was built without ROS.
RecordSummary RecordSimulatedBag(Simulator* simulator, const std::filesystem::path& path,
                                 const RecordOptions& options);

}  // namespace retrace
