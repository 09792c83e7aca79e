#pragma once

// Ground-truth trajectories of public datasets: reading, writing, interpolation.
//
// Every reader returns a list of `TimedPose`s in file order. A pose is `world_from_cam` (or `world_from_body` for
// EuRoC, see ReadEurocPoses): it maps points from the camera (body) frame into the dataset's world frame, so its
// translation is the position of the camera centre in the world.
//
// Rotations read from files are re-orthonormalised (nearest rotation in the Frobenius norm, via SVD): KITTI stores
// 7 significant digits, so its matrices are rotations only to ~1e-7. A matrix that is far from a rotation (or a
// quaternion that is far from unit length) is bad input and throws InputError naming the file and the line.

#include <filesystem>
#include <optional>
#include <vector>

#include "retrace/util/types.h"

namespace retrace {

struct TimedPose {
  // Seconds. KITTI: from times.txt (or the line index); TUM: as in the file; EuRoC: nanoseconds * 1e-9.
  double timestamp = 0;
  Rigid3d world_from_cam;
};

// KITTI odometry poses: one line per frame with 12 numbers, the row-major 3x4 matrix [R|t] = world_from_cam (the
// world frame is the first camera). Timestamps come from `times_txt` (one number per line, same number of lines as
// poses) when given, else the timestamp is the line index (0, 1, 2, ...). Empty lines are not allowed.
std::vector<TimedPose> ReadKittiPoses(const std::filesystem::path& poses_txt,
                                      const std::filesystem::path& times_txt = {});

// TUM RGB-D format: `timestamp tx ty tz qx qy qz qw` per line (world_from_cam, Hamilton quaternion, normalised on
// read); lines starting with '#' and empty lines are ignored.
std::vector<TimedPose> ReadTumPoses(const std::filesystem::path& path);

// EuRoC MAV `state_groundtruth_estimate0/data.csv`: `timestamp [ns], p_x, p_y, p_z, q_w, q_x, q_y, q_z, ...`
// (further columns — velocity, biases — are ignored); a header line starting with '#'.
// NOTE: these are BODY (IMU) poses world_from_body, not camera poses. The camera pose is
// world_from_body * body_from_cam, with body_from_cam = T_BS of cam0/sensor.yaml.
std::vector<TimedPose> ReadEurocPoses(const std::filesystem::path& path);

// Writes KITTI poses (12 numbers per line, shortest exact decimal representation) and, if `times_txt` is given,
// the timestamps one per line. Throws InputError naming the file when it cannot be written.
void WriteKittiPoses(const std::filesystem::path& poses_txt, const std::vector<TimedPose>& poses,
                     const std::filesystem::path& times_txt = {});

// Writes TUM format (`timestamp tx ty tz qx qy qz qw`) with a '#' header line.
void WriteTumPoses(const std::filesystem::path& path, const std::vector<TimedPose>& poses);

// Pose at time `t` on a trajectory sorted by timestamp: translation interpolated linearly, rotation by slerp between
// the two neighbouring poses. nullopt when `t` lies outside [first, last] timestamp or the trajectory is empty.
std::optional<Rigid3d> InterpolatePose(const std::vector<TimedPose>& poses, double t);

// Length of the polyline through the camera centres (translations of world_from_cam), in the trajectory's units
// (metres for KITTI, TUM and EuRoC).
double TrajectoryLength(const std::vector<TimedPose>& poses);

// Nearest rotation matrix to `m` (SVD projection, det = +1).
Matrix3d NearestRotation(const Matrix3d& m);

}  // namespace retrace
