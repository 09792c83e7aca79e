#include "retrace/dataset/sequence.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>
#include <opencv2/videoio/registry.hpp>
#include <spdlog/spdlog.h>

#include "retrace/dataset/text_io.h"
#include "retrace/image/image_utils.h"
#include "retrace/util/error.h"

namespace retrace {
namespace fs = std::filesystem;

namespace {

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

bool IsImageFile(const fs::path& path) {
  static const char* const kExtensions[] = {".png", ".jpg", ".jpeg", ".pgm", ".bmp", ".tif", ".tiff"};
  const std::string ext = Lower(path.extension().string());
  return std::any_of(std::begin(kExtensions), std::end(kExtensions), [&](const char* e) { return ext == e; });
}

bool IsDir(const fs::path& path) {
  std::error_code ec;
  return fs::is_directory(path, ec);
}

bool IsFile(const fs::path& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec);
}

std::optional<fs::path> IfFile(const fs::path& path) {
  return IsFile(path) ? std::optional<fs::path>(path) : std::nullopt;
}

// Image files directly in `dir`, sorted by file name.
std::vector<fs::path> ListImages(const fs::path& dir) {
  std::vector<fs::path> files;
  std::error_code ec;
  for (const fs::directory_entry& entry : fs::directory_iterator(dir, ec)) {
    if (entry.is_regular_file(ec) && IsImageFile(entry.path())) files.push_back(entry.path());
  }
  if (ec) throw InputError(dir.string(), "cannot list the folder: " + ec.message());
  std::sort(files.begin(), files.end(),
            [](const fs::path& a, const fs::path& b) { return a.filename().string() < b.filename().string(); });
  return files;
}

// One listed frame of an image-file based sequence.
struct ImageEntry {
  fs::path file;
  double timestamp = 0;
};

// Folder, KITTI and EuRoC: a list of image files with timestamps.
class ImageListSequence : public Sequence {
 public:
  ImageListSequence(std::string layout, fs::path root, std::vector<ImageEntry> entries,
                    std::optional<fs::path> calibration, std::optional<fs::path> ground_truth,
                    std::string calibration_camera = "")
      : layout_(std::move(layout)),
        root_(std::move(root)),
        entries_(std::move(entries)),
        calibration_(std::move(calibration)),
        ground_truth_(std::move(ground_truth)),
        calibration_camera_(std::move(calibration_camera)) {}

  size_t size() const override { return entries_.size(); }

  std::optional<Frame> Next() override {
    while (cursor_ < entries_.size()) {
      Frame frame;
      if (Read(cursor_++, &frame)) return frame;
    }
    return std::nullopt;
  }

  bool Read(size_t index, Frame* frame) override {
    if (index >= entries_.size()) return false;
    const ImageEntry& entry = entries_[index];
    const std::string name = entry.file.filename().string();
    if (!IsFile(entry.file)) {
      ReportUnreadable(name, entry.file.string(), "missing");
      return false;
    }
    cv::Mat image;
    try {
      image = cv::imread(entry.file.string(), cv::IMREAD_UNCHANGED);
    } catch (const cv::Exception& e) {
      image.release();
    }
    if (image.empty()) {
      ReportUnreadable(name, entry.file.string(), "cannot be decoded as an image");
      return false;
    }
    CheckFrameSize(image.size(), entry.file.string());
    frame->index = index;
    frame->source_index = index;
    frame->name = name;
    frame->timestamp = entry.timestamp;
    frame->image = ToGray8(image);
    return true;
  }

  void Rewind() override { cursor_ = 0; }
  std::optional<fs::path> calibration_file() const override { return calibration_; }
  std::string calibration_camera() const override { return calibration_camera_; }
  std::optional<fs::path> ground_truth_file() const override { return ground_truth_; }
  std::string layout() const override { return layout_; }
  fs::path path() const override { return root_; }

 private:
  std::string layout_;
  fs::path root_;
  std::vector<ImageEntry> entries_;
  std::optional<fs::path> calibration_;
  std::optional<fs::path> ground_truth_;
  std::string calibration_camera_;
  size_t cursor_ = 0;
};

class VideoSequence : public Sequence {
 public:
  explicit VideoSequence(fs::path file) : file_(std::move(file)) {
    // FFmpeg reads every common container; asking only it avoids the noisy fall-through of other backends (GStreamer,
    // image-sequence) on files that are not videos.
    const int backend = cv::videoio_registry::hasBackend(cv::CAP_FFMPEG) ? cv::CAP_FFMPEG : cv::CAP_ANY;
    if (!capture_.open(file_.string(), backend) || !capture_.isOpened()) {
      throw InputError(file_.string(), "cannot be opened as a video (unknown format or codec)");
    }
    const double count = capture_.get(cv::CAP_PROP_FRAME_COUNT);
    size_ = count > 0 && std::isfinite(count) ? static_cast<size_t>(std::lround(count)) : 0;
    fps_ = capture_.get(cv::CAP_PROP_FPS);
  }

  size_t size() const override { return size_; }

  std::optional<Frame> Next() override {
    Frame frame;
    if (!Grab(next_index_, &frame)) return std::nullopt;
    ++next_index_;
    return frame;
  }

  bool Read(size_t index, Frame* frame) override {
    if (size_ > 0 && index >= size_) return false;
    if (index != next_index_) capture_.set(cv::CAP_PROP_POS_FRAMES, static_cast<double>(index));
    const bool ok = Grab(index, frame);
    // Restore the streaming position of Next().
    capture_.set(cv::CAP_PROP_POS_FRAMES, static_cast<double>(next_index_));
    return ok;
  }

  void Rewind() override {
    next_index_ = 0;
    capture_.set(cv::CAP_PROP_POS_FRAMES, 0.0);
  }

  std::string layout() const override { return "video"; }
  fs::path path() const override { return file_; }

 private:
  // Reads the frame at the current stream position, which the caller has placed at `index`.
  bool Grab(size_t index, Frame* frame) {
    cv::Mat image;
    if (!capture_.read(image) || image.empty()) return false;
    const double msec = capture_.get(cv::CAP_PROP_POS_MSEC);
    frame->index = index;
    frame->source_index = index;
    frame->name = fmt::format("frame_{:06d}", index);
    if (std::isfinite(msec) && msec >= 0 && !(index > 0 && msec == 0)) {
      frame->timestamp = msec * 1e-3;
    } else {
      frame->timestamp = fps_ > 0 ? static_cast<double>(index) / fps_ : static_cast<double>(index);
    }
    frame->image = ToGray8(image);
    return true;
  }

  fs::path file_;
  cv::VideoCapture capture_;
  size_t size_ = 0;
  double fps_ = 0;
  size_t next_index_ = 0;
};

// KITTI odometry: root/image_N/NNNNNN.png (N = `camera`, 0-3: the grey pair, then the colour pair), root/times.txt,
// root/calib.txt (its line PN), optional root/poses.txt (the poses of camera 0, the grey left one; the others are
// rigidly fixed to it, at 0.06-0.54 m).
std::unique_ptr<Sequence> OpenKitti(const fs::path& root, int camera, const SequenceOptions& options) {
  const std::string image_folder = fmt::format("image_{}", camera);
  const fs::path image_dir = root / image_folder;
  const fs::path times_txt = root / "times.txt";
  const std::vector<fs::path> files = ListImages(image_dir);
  std::vector<ImageEntry> entries;
  if (IsFile(times_txt)) {
    const std::vector<double> times = ReadTimestamps(times_txt);
    // Frames are named by their index; a file beyond the listed count means times.txt does not fit the images.
    for (const fs::path& file : files) {
      const std::string stem = file.stem().string();
      char* end = nullptr;
      errno = 0;
      const unsigned long long number = std::strtoull(stem.c_str(), &end, 10);
      if (end == stem.c_str() || *end != '\0') continue;  // not a frame file (e.g. a preview)
      if (number >= times.size()) {
        throw InputError(times_txt.string(), fmt::format("has {} lines but {} holds frame {}", times.size(),
                                                         image_folder, file.filename().string()));
      }
    }
    for (size_t i = 0; i < times.size(); ++i) {
      entries.push_back({image_dir / fmt::format("{:06d}.png", i), times[i]});
    }
  } else {
    CheckInput(!files.empty(), image_dir.string(), "no images in the folder and no times.txt next to it");
    spdlog::warn("{}: no times.txt; timestamps are index / {} fps", root.string(), options.frame_rate);
    for (size_t i = 0; i < files.size(); ++i) {
      entries.push_back({files[i], static_cast<double>(i) / options.frame_rate});
    }
  }
  std::optional<fs::path> calibration = IfFile(root / "camera.yaml");
  if (!calibration) calibration = IfFile(root / "calib.txt");
  return std::make_unique<ImageListSequence>("kitti", root, std::move(entries), calibration,
                                             IfFile(root / "poses.txt"), fmt::format("P{}", camera));
}

// EuRoC MAV: cam_dir/data.csv (`#timestamp [ns],filename`) and cam_dir/data/<filename>.
std::unique_ptr<Sequence> OpenEuroc(const fs::path& cam_dir) {
  const fs::path csv = cam_dir / "data.csv";
  const std::string file = csv.string();
  std::vector<ImageEntry> entries;
  for (const TextLine& line : ReadTextLines(csv, /*skip_comments_and_empty=*/true)) {
    const size_t comma = line.text.find(',');
    if (comma == std::string::npos) {
      throw InputError(file, fmt::format("line {}: expected 'timestamp [ns],filename'", line.number));
    }
    std::string stamp = line.text.substr(0, comma);
    std::string name = line.text.substr(comma + 1);
    const auto trim = [](std::string& s) {
      s.erase(0, s.find_first_not_of(" \t"));
      s.erase(s.find_last_not_of(" \t") + 1);
    };
    trim(stamp);
    trim(name);
    char* end = nullptr;
    errno = 0;
    const unsigned long long ns = std::strtoull(stamp.c_str(), &end, 10);
    if (stamp.empty() || *end != '\0' || errno == ERANGE || stamp[0] == '-') {
      throw InputError(file, fmt::format("line {}: '{}' is not a timestamp in nanoseconds", line.number, stamp));
    }
    if (name.empty() || name.find(',') != std::string::npos) {
      throw InputError(file, fmt::format("line {}: expected one file name after the timestamp", line.number));
    }
    entries.push_back({cam_dir / "data" / name, static_cast<double>(ns) * 1e-9});
  }
  CheckInput(!entries.empty(), file, "lists no frames");
  return std::make_unique<ImageListSequence>("euroc", cam_dir, std::move(entries), IfFile(cam_dir / "sensor.yaml"),
                                             IfFile(cam_dir.parent_path() / "state_groundtruth_estimate0" /
                                                    "data.csv"));
}

std::unique_ptr<Sequence> OpenFolder(const fs::path& dir, const SequenceOptions& options) {
  const std::vector<fs::path> files = ListImages(dir);
  CheckInput(!files.empty(), dir.string(),
             "no images (png, jpg, jpeg, pgm, bmp, tif) and no KITTI (image_0/ to image_3/) or EuRoC (mav0/) layout");
  std::vector<ImageEntry> entries;
  const fs::path times_txt = dir / "times.txt";
  if (IsFile(times_txt)) {
    const std::vector<double> times = ReadTimestamps(times_txt);
    if (times.size() != files.size()) {
      throw InputError(times_txt.string(),
                       fmt::format("has {} lines but the folder holds {} images", times.size(), files.size()));
    }
    for (size_t i = 0; i < files.size(); ++i) entries.push_back({files[i], times[i]});
  } else {
    for (size_t i = 0; i < files.size(); ++i) {
      entries.push_back({files[i], static_cast<double>(i) / options.frame_rate});
    }
  }
  return std::make_unique<ImageListSequence>("folder", dir, std::move(entries), IfFile(dir / "camera.yaml"),
                                             std::nullopt);
}

}  // namespace

void Sequence::CheckFrameSize(const cv::Size& size, const std::string& file) {
  // image_size() reads the first readable frame through Read(), which calls this with the size still unknown.
  const cv::Size first = image_size();
  if (first.empty() || size == first) return;
  throw InputError(file, fmt::format("image is {}x{} but the sequence's first frame is {}x{} (all frames of a "
                                     "sequence must come from one camera at one size)",
                                     size.width, size.height, first.width, first.height));
}

cv::Size Sequence::image_size() {
  if (!image_size_) {
    image_size_ = cv::Size();
    Frame frame;
    const size_t n = size();
    if (n > 0) {
      for (size_t i = 0; i < n; ++i) {
        if (Read(i, &frame)) {
          image_size_ = frame.image.size();
          break;
        }
      }
    } else if (Read(0, &frame)) {
      image_size_ = frame.image.size();
    }
  }
  return *image_size_;
}

void Sequence::ReportUnreadable(const std::string& name, const std::string& file, const std::string& why) {
  if (!reported_.insert(name).second) return;
  spdlog::warn("{}: {}; frame skipped", file, why);
  skipped_.push_back(name);
}

std::unique_ptr<Sequence> OpenSequence(const fs::path& path, const SequenceOptions& options) {
  CheckInput(options.Check(), path.string(), "invalid sequence options (frame_rate must be > 0)");
  std::error_code ec;
  CheckInput(fs::exists(path, ec), path.string(), "no such file or folder");
  if (!IsDir(path)) {
    CheckInput(IsFile(path), path.string(), "neither a folder nor a video file");
    return std::make_unique<VideoSequence>(path);
  }
  // Normalise "foo/" to "foo" so that filename() and parent_path() behave.
  const fs::path dir = path.has_filename() ? path : path.parent_path();
  // KITTI odometry: the grey left camera (image_0) when the folder has it, else the colour left one (image_2), else
  // the right ones; or the image_N folder given.
  for (const int camera : {0, 2, 1, 3}) {
    if (IsDir(dir / fmt::format("image_{}", camera))) return OpenKitti(dir, camera, options);
  }
  for (int camera = 0; camera <= 3; ++camera) {
    if (dir.filename() == fmt::format("image_{}", camera) &&
        (IsFile(dir.parent_path() / "times.txt") || IsFile(dir.parent_path() / "calib.txt"))) {
      return OpenKitti(dir.parent_path(), camera, options);
    }
  }
  // EuRoC MAV.
  for (const fs::path& cam_dir : {dir / "mav0" / "cam0", dir / "cam0", dir}) {
    if (IsFile(cam_dir / "data.csv") && IsDir(cam_dir / "data")) return OpenEuroc(cam_dir);
  }
  return OpenFolder(dir, options);
}

SubsampledSequence::SubsampledSequence(std::unique_ptr<Sequence> base, size_t step, size_t offset)
    : base_(std::move(base)), step_(std::max<size_t>(step, 1)), offset_(offset) {}

size_t SubsampledSequence::size() const {
  const size_t n = base_->size();
  return n > offset_ ? (n - offset_ + step_ - 1) / step_ : 0;
}

std::optional<Frame> SubsampledSequence::Next() {
  while (std::optional<Frame> frame = base_->Next()) {
    // Select by the position in the base listing (which may itself be subsampled); source_index is kept.
    const size_t position = frame->index;
    if (position < offset_ || (position - offset_) % step_ != 0) continue;
    frame->index = (position - offset_) / step_;
    return frame;
  }
  return std::nullopt;
}

bool SubsampledSequence::Read(size_t index, Frame* frame) {
  if (!base_->Read(offset_ + index * step_, frame)) return false;
  frame->index = index;
  return true;
}

void SubsampledSequence::Rewind() { base_->Rewind(); }

}  // namespace retrace
