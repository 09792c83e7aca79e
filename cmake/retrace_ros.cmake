# ROS 1 as Debian 12 packages it (scripts/install-deps): roscpp, rosbag_storage and the message headers, found
# without catkin.
#
# Debian's catkin-generated rosbagConfig.cmake pulls in the ROS 2 pluginlib (Debian builds rosbag_storage against
# it), whose ament CMake hooks run `python3` with ament_package: that fails under any python3 other than Debian's
# (a virtualenv, pyenv). The libraries and headers are plain files, so they are found directly here instead: roscpp
# and the message packages through their pkg-config files, rosbag_storage (whose .pc file requires a pluginlib.pc
# that Debian does not ship) and the include folders of its ROS 2 plugin headers by path.
#
# Defines, when everything is found, the interface target retrace_ros1_deps and RETRACE_ROS_FOUND = TRUE; otherwise
# RETRACE_ROS_FOUND = FALSE and RETRACE_ROS_MISSING names what is missing.

set(RETRACE_ROS_FOUND FALSE)
set(RETRACE_ROS_MISSING "")

find_package(PkgConfig QUIET)
if(PkgConfig_FOUND)
  # roslz4: rosbag_storage's chunk compression; rostime and console_bridge: used by rosbag_storage's headers.
  pkg_check_modules(RETRACE_ROS1 QUIET IMPORTED_TARGET
    roscpp rostime roslz4 console_bridge sensor_msgs geometry_msgs std_msgs diagnostic_msgs)
  if(NOT RETRACE_ROS1_FOUND)
    list(APPEND RETRACE_ROS_MISSING "pkg-config: roscpp sensor_msgs geometry_msgs std_msgs diagnostic_msgs")
  endif()
else()
  list(APPEND RETRACE_ROS_MISSING "pkg-config")
endif()

find_library(RETRACE_ROSBAG_STORAGE_LIBRARY NAMES rosbag_storage)
find_path(RETRACE_ROSBAG_INCLUDE_DIR NAMES rosbag/bag.h)
# rosbag/bag.h includes <pluginlib/class_loader.hpp>, which includes class_loader, rcpputils, rcutils and
# ament_index_cpp headers; Debian installs each in /usr/include/<package>/<package>/.
set(_retrace_ros_plugin_include_dirs "")
foreach(_header IN ITEMS pluginlib/class_loader.hpp class_loader/class_loader.hpp rcpputils/shared_library.hpp
                         rcutils/types.h ament_index_cpp/get_package_prefix.hpp)
  string(REGEX REPLACE "/.*" "" _package "${_header}")
  string(MAKE_C_IDENTIFIER "${_package}" _id)
  find_path(RETRACE_ROS_${_id}_INCLUDE_DIR NAMES "${_header}" PATH_SUFFIXES "${_package}")
  if(RETRACE_ROS_${_id}_INCLUDE_DIR)
    list(APPEND _retrace_ros_plugin_include_dirs "${RETRACE_ROS_${_id}_INCLUDE_DIR}")
  else()
    list(APPEND RETRACE_ROS_MISSING "${_header}")
  endif()
endforeach()
if(NOT RETRACE_ROSBAG_STORAGE_LIBRARY)
  list(APPEND RETRACE_ROS_MISSING "librosbag_storage")
endif()
if(NOT RETRACE_ROSBAG_INCLUDE_DIR)
  list(APPEND RETRACE_ROS_MISSING "rosbag/bag.h")
endif()

if(RETRACE_ROS_MISSING STREQUAL "")
  set(RETRACE_ROS_FOUND TRUE)
  add_library(retrace_ros1_deps INTERFACE)
  list(REMOVE_DUPLICATES _retrace_ros_plugin_include_dirs)
  # The ROS headers are third-party code: SYSTEM keeps their warnings out of retrace's.
  target_include_directories(retrace_ros1_deps SYSTEM INTERFACE ${RETRACE_ROSBAG_INCLUDE_DIR}
                             ${_retrace_ros_plugin_include_dirs})
  target_link_libraries(retrace_ros1_deps INTERFACE ${RETRACE_ROSBAG_STORAGE_LIBRARY} PkgConfig::RETRACE_ROS1)
endif()
