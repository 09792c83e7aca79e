#pragma once

// Writes an image sequence in the KITTI odometry layout, so that everything retrace produces (simulator renders,
// perturbed copies of real sequences) can be read back by OpenSequence and ReadKittiPoses:
//
//   dir/image_0/000000.png, 000001.png, ...   the frames
//   dir/times.txt                             one timestamp (s) per frame
//   dir/poses.txt                             one row-major 3x4 world_from_cam per frame (if poses are given)
//   dir/calib.txt                             P0..P3 (all equal to the given P0; written by WriteCalibration)
//
// times.txt and poses.txt are appended and flushed after every frame, so a crash loses nothing already written.
// Numbers are written in the shortest decimal form that reads back to the same double.

#include <filesystem>
#include <fstream>

#include <opencv2/core.hpp>

#include "retrace/util/types.h"

namespace retrace {

class KittiSequenceWriter {
 public:
  // Creates dir and dir/image_0 and starts fresh times.txt / poses.txt (existing ones are overwritten). Throws
  // InputError naming the folder or file when it cannot be created.
  explicit KittiSequenceWriter(const std::filesystem::path& dir);

  // Writes dir/calib.txt with lines "P0: ..." to "P3: ..." (12 numbers each, row-major), P1..P3 = P0.
  void WriteCalibration(const Matrix34d& p0);

  // Writes image_0/NNNNNN.png (NNNNNN = frames_written()) and appends the timestamp and the pose. 8-bit images
  // (gray or colour) are stored as given, other depths as 8-bit gray (see ToGray8).
  void WriteFrame(const cv::Mat& image, double timestamp, const Rigid3d& world_from_cam);
  // The same without ground truth: no poses.txt is written. A writer must not mix both kinds of frames
  // (std::logic_error: a programming error, not bad input).
  void WriteFrame(const cv::Mat& image, double timestamp);

  size_t frames_written() const { return frames_written_; }
  const std::filesystem::path& dir() const { return dir_; }

 private:
  void WriteImageAndTime(const cv::Mat& image, double timestamp);

  std::filesystem::path dir_;
  std::ofstream times_;
  std::ofstream poses_;
  size_t frames_written_ = 0;
  size_t poses_written_ = 0;
};

}  // namespace retrace
