#pragma once

// Image sequences: one interface over a folder of images, a video file, the KITTI odometry layout and the EuRoC
// MAV layout. Frames come out as 8-bit gray images with a timestamp in seconds.
//
// Reading is streaming (Next) or random access (Read). A frame file that is listed but missing or unreadable is not
// an error of the whole sequence (real recordings have holes): it is reported once with spdlog::warn naming the file,
// recorded in skipped(), and Next() moves on to the following readable frame. A readable frame of another size than
// the first is an error (InputError naming its file): it is not the same camera's recording. Structural problems —
// a path that does not exist, a folder without images, a times.txt whose line count does not match the images, a
// garbage CSV — throw InputError from OpenSequence naming the file and the problem.

#include <cstddef>
#include <filesystem>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace retrace {

struct Frame {
  // Position of the frame in the sequence it was read from (0-based). For a SubsampledSequence this is the position
  // in the subsampled sequence; `source_index` is the position in the original sequence.
  size_t index = 0;
  size_t source_index = 0;
  // File name without folder (e.g. "000042.png"), or "frame_000042" for a video.
  std::string name;
  // Seconds (KITTI: times.txt; EuRoC: ns * 1e-9, absolute epoch times ~1.4e9 s, so a double keeps ~0.2 us;
  // folder: times.txt or index / frame_rate; video: CAP_PROP_POS_MSEC of the frame, else index / fps).
  double timestamp = 0;
  // 8-bit single-channel gray.
  cv::Mat image;
};

class Sequence {
 public:
  virtual ~Sequence() = default;

  // Number of frames the sequence lists (including unreadable ones), 0 when unknown (some videos).
  virtual size_t size() const = 0;

  // The next READABLE frame, or nullopt at the end. Unreadable frames are warned about (once), recorded in skipped()
  // and passed over.
  virtual std::optional<Frame> Next() = 0;

  // Reads frame `index` (0-based, as listed). Returns false if it does not exist or cannot be read (an unreadable
  // listed frame is recorded in skipped() as by Next). Does not move the streaming position of Next().
  virtual bool Read(size_t index, Frame* frame) = 0;

  // Next() starts again at the first frame.
  virtual void Rewind() = 0;

  // Names (as in Frame::name) of the frames found unreadable so far, in the order they were found.
  virtual const std::vector<std::string>& skipped() const { return skipped_; }

  // The calibration file that belongs to the sequence, if any (KITTI: camera.yaml if present, else calib.txt; EuRoC:
  // cam0/sensor.yaml; folder: camera.yaml if present). Reading it is the camera layer's job.
  virtual std::optional<std::filesystem::path> calibration_file() const { return std::nullopt; }
  // Which camera of the calibration file the frames come from, for files that hold several: a KITTI folder's
  // image_0 .. image_3 are calib.txt's "P0" .. "P3". Empty: the file's only (or first) camera.
  virtual std::string calibration_camera() const { return ""; }

  // The ground-truth trajectory file, if any (KITTI: poses.txt, camera poses; EuRoC:
  // mav0/state_groundtruth_estimate0/data.csv, BODY poses — see ReadEurocPoses).
  virtual std::optional<std::filesystem::path> ground_truth_file() const { return std::nullopt; }

  // "folder", "video", "kitti" or "euroc".
  virtual std::string layout() const = 0;

  // The root of the sequence as detected (the folder containing image_0/ for KITTI, the cam0 folder for EuRoC,
  // the folder or video file otherwise).
  virtual std::filesystem::path path() const = 0;

  // Size of the first readable frame (cached after the first call); an empty size if no frame is readable.
  cv::Size image_size();

 protected:
  // Throws InputError naming `file` when a frame's size differs from the first readable frame's: a sequence whose
  // frames change size mid-way is not one camera's recording, and resizing it silently would bend its calibration.
  void CheckFrameSize(const cv::Size& size, const std::string& file);

  // Warns (once per name) and records a frame that could not be read.
  void ReportUnreadable(const std::string& name, const std::string& file, const std::string& why);

 private:
  std::vector<std::string> skipped_;
  std::set<std::string> reported_;
  std::optional<cv::Size> image_size_;
};

struct SequenceOptions {
  // Frame rate assumed for an image folder without times.txt: timestamp = index / frame_rate. Must be > 0.
  double frame_rate = 1.0;

  bool Check() const { return frame_rate > 0; }
};

// Opens the sequence at `path`, detecting its layout:
//  - KITTI odometry: a folder with image_0/ (and times.txt, optional calib.txt, camera.yaml, poses.txt); `path` may
//    also be the image_0 folder itself. Frames are image_0/NNNNNN.png for every line of times.txt.
//  - EuRoC MAV: the folder containing mav0/, mav0 itself, or mav0/cam0: cam0/data.csv (`#timestamp [ns],filename`)
//    lists the frames in cam0/data/.
//  - a folder of images (png, jpg, jpeg, pgm, bmp, tif, tiff; sorted by name), with an optional times.txt of one
//    time per line (must match the number of images).
//  - any regular file: a video opened with cv::VideoCapture.
// Throws InputError naming the file and the problem when the path does not exist or the layout is broken.
std::unique_ptr<Sequence> OpenSequence(const std::filesystem::path& path, const SequenceOptions& options = {});

// Every `step`-th frame of `base`, starting at frame `offset` (listing positions of the original sequence):
// offset, offset + step, offset + 2 step, ... "Teach on even frames, repeat on odd frames" is
// SubsampledSequence(Open(p), 2, 0) and SubsampledSequence(Open(p), 2, 1).
// Frame::index is the position in THIS sequence, Frame::source_index the listing position in the original
// (`index = (source_index - offset) / step`). Timestamps and names are the original ones. Unreadable frames of the
// original are skipped as by the base sequence; skipped() reports the base sequence's list.
class SubsampledSequence : public Sequence {
 public:
  SubsampledSequence(std::unique_ptr<Sequence> base, size_t step, size_t offset = 0);

  size_t size() const override;
  std::optional<Frame> Next() override;
  bool Read(size_t index, Frame* frame) override;
  void Rewind() override;
  const std::vector<std::string>& skipped() const override { return base_->skipped(); }
  std::optional<std::filesystem::path> calibration_file() const override { return base_->calibration_file(); }
  std::optional<std::filesystem::path> ground_truth_file() const override { return base_->ground_truth_file(); }
  std::string layout() const override { return base_->layout(); }
  std::filesystem::path path() const override { return base_->path(); }

  size_t step() const { return step_; }
  size_t offset() const { return offset_; }

 private:
  std::unique_ptr<Sequence> base_;
  size_t step_;
  size_t offset_;
};

}  // namespace retrace
