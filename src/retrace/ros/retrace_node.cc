// retrace_node: repeat as a ROS 1 node (repeat_node.h has its topics and parameters). Usage:
//   retrace_node _map:=route.db [_speed:=0.5] [_camera:=camera.yaml or _use_camera_info:=true]
//                image:=/camera/image_raw [cmd_vel:=/robot/cmd_vel]

#include <cstdio>
#include <cstring>
#include <iostream>
#include <memory>

#include <ros/ros.h>

#include "retrace/ros/repeat_node.h"
#include "retrace/util/error.h"

int main(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--help") == 0 || std::strcmp(argv[i], "-h") == 0) {
      std::cout << "retrace_node: localize a camera in a taught map and steer along the route (ROS 1)\n"
                   "usage: retrace_node _map:=MAP [_speed:=0.5] [_camera:=FILE | _use_camera_info:=true]\n"
                   "                    [_compressed:=true] [_start_arc:=ARC] [_steering_gain:=1.0] ...\n"
                   "                    image:=/camera/image_raw [cmd_vel:=...]\n"
                   "subscribes image (or image/compressed), publishes cmd_vel, ~state (JSON), /diagnostics;\n"
                   "README.md \"ROS\" lists every parameter.\n";
      return 0;
    }
  }
  // Line-buffered output: ROS_INFO lines reach a log file or pipe as they are written, not at exit.
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  ros::init(argc, argv, "retrace_node");
  ros::NodeHandle node;
  ros::NodeHandle private_node("~");
  std::unique_ptr<retrace::RepeatNode> repeat;
  try {
    repeat = std::make_unique<retrace::RepeatNode>(node, private_node, retrace::ReadRepeatNodeOptions(private_node));
  } catch (const std::exception& e) {  // retrace::InputError: a bad parameter, map or camera
    std::cerr << "retrace_node: error: " << e.what() << "\n";
    return 1;
  }
  ros::spin();
  repeat.reset();
  return 0;
}
