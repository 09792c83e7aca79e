#include "retrace/dataset/kitti_writer.h"

#include <stdexcept>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>

#include "retrace/dataset/text_io.h"
#include "retrace/image/image_utils.h"
#include "retrace/util/error.h"

namespace retrace {
namespace fs = std::filesystem;

KittiSequenceWriter::KittiSequenceWriter(const fs::path& dir) : dir_(dir) {
  std::error_code ec;
  fs::create_directories(dir_ / "image_0", ec);
  CheckInput(!ec && fs::is_directory(dir_ / "image_0"), (dir_ / "image_0").string(),
             "cannot create the folder" + (ec ? ": " + ec.message() : std::string()));
  times_.open(dir_ / "times.txt", std::ios::trunc);
  CheckInput(times_.is_open(), (dir_ / "times.txt").string(), "cannot open the file for writing");
  // A stale poses.txt from an earlier run must not survive next to new frames.
  fs::remove(dir_ / "poses.txt", ec);
}

void KittiSequenceWriter::WriteCalibration(const Matrix34d& p0) {
  const fs::path path = dir_ / "calib.txt";
  std::ofstream out(path, std::ios::trunc);
  CheckInput(out.is_open(), path.string(), "cannot open the file for writing");
  std::string numbers;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) numbers += (numbers.empty() ? "" : " ") + fmt::format("{}", p0(r, c));
  }
  for (int i = 0; i < 4; ++i) out << 'P' << i << ": " << numbers << '\n';
  out.flush();
  CheckInput(static_cast<bool>(out), path.string(), "cannot write the file");
}

void KittiSequenceWriter::WriteImageAndTime(const cv::Mat& image, double timestamp) {
  const fs::path file = dir_ / "image_0" / fmt::format("{:06d}.png", frames_written_);
  CheckInput(!image.empty(), file.string(), "cannot write an empty image");
  const cv::Mat to_write = image.depth() == CV_8U && (image.channels() == 1 || image.channels() == 3)
                               ? image
                               : ToGray8(image);
  bool ok = false;
  try {
    ok = cv::imwrite(file.string(), to_write);
  } catch (const cv::Exception& e) {
    throw InputError(file.string(), std::string("cannot write the image: ") + e.what());
  }
  CheckInput(ok, file.string(), "cannot write the image");
  times_ << fmt::format("{}", timestamp) << '\n';
  times_.flush();
  CheckInput(static_cast<bool>(times_), (dir_ / "times.txt").string(), "cannot write the file");
  ++frames_written_;
}

void KittiSequenceWriter::WriteFrame(const cv::Mat& image, double timestamp, const Rigid3d& world_from_cam) {
  if (poses_written_ != frames_written_) {
    throw std::logic_error("KittiSequenceWriter: frames with and without poses mixed");
  }
  if (!poses_.is_open()) {
    poses_.open(dir_ / "poses.txt", std::ios::trunc);
    CheckInput(poses_.is_open(), (dir_ / "poses.txt").string(), "cannot open the file for writing");
  }
  WriteImageAndTime(image, timestamp);
  poses_ << FormatKittiPose(world_from_cam) << '\n';
  poses_.flush();
  CheckInput(static_cast<bool>(poses_), (dir_ / "poses.txt").string(), "cannot write the file");
  ++poses_written_;
}

void KittiSequenceWriter::WriteFrame(const cv::Mat& image, double timestamp) {
  if (poses_written_ > 0) throw std::logic_error("KittiSequenceWriter: frames with and without poses mixed");
  WriteImageAndTime(image, timestamp);
}

}  // namespace retrace
