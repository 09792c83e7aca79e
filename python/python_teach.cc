// retrace.Teacher: teach (teach/teacher.h), fed numpy images frame by frame, writing its map file the way
// `retrace teach` does: staged in MAP.incomplete under MAP.lock and moved onto MAP only when teach finished
// (map/map_database.h StagedMap), with the camera and settings repeat needs (teach/teach_settings.h).

#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include <fmt/format.h>
#include <pybind11/stl.h>
#include <spdlog/spdlog.h>

#include "python_common.h"
#include "retrace/image/image_utils.h"
#include "retrace/map/map_database.h"
#include "retrace/teach/teach_settings.h"
#include "retrace/teach/teacher.h"
#include "retrace/util/error.h"

namespace retrace::python {
namespace {

class PythonTeacher {
 public:
  PythonTeacher(const std::filesystem::path& path, const CameraModel& camera, int width,
                const std::optional<std::string>& source, bool overwrite, const TeachOptions& options,
                const MapDatabaseOptions& storage, const std::string& method, double camera_height)
      : camera_(width > 0 && width != camera.width() ? camera.Scaled(static_cast<double>(width) / camera.width())
                                                     : camera.Clone()) {
    std::string error;
    if (!options.Check(&error)) throw InputError("teach options", error);
    py::gil_scoped_release release;
    staged_ = StagedMap::Begin(path, storage, overwrite);
    MapDatabase* database = staged_->database();
    if (source) database->SetMetadata("source_sequence", *source);
    database->SetMetadata("method", method);
    teacher_ = std::make_unique<Teacher>(*camera_, options, database);
    WriteTeachSettings(*camera_, options, *teacher_, database, camera_height);
  }

  void AddFrame(const py::handle& image, std::optional<double> timestamp, std::optional<std::string> name) {
    Frame frame = FrameFromObject(image, next_index_, timestamp, name, "image");
    next_index_ = frame.index + 1;
    py::gil_scoped_release release;
    const std::lock_guard<std::mutex> lock(mutex_);
    CheckOpen();
    // Frames of another width are resized to the camera's (Teacher(width=...)), as `retrace teach --width` does.
    if (frame.image.cols != camera_->width()) {
      cv::Mat resized;
      ResizeToWidth(frame.image, camera_->width(), &resized);
      if (resized.rows == camera_->height()) frame.image = resized;
    }
    teacher_->AddFrame(frame);
  }

  // Registers the last key-image, closes the loop and moves the map into place.
  void Finish() {
    py::gil_scoped_release release;
    const std::lock_guard<std::mutex> lock(mutex_);
    CheckOpen();
    teacher_->Finish();
    staged_->database()->Checkpoint();
    staged_->Commit();
    staged_.reset();  // the lock file goes
    finished_ = true;
  }

  // Gives up: MAP stays as it was; what was taught stays in MAP.incomplete, marked incomplete.
  void Abandon() {
    py::gil_scoped_release release;
    const std::lock_guard<std::mutex> lock(mutex_);
    if (!staged_) return;
    spdlog::warn("teach abandoned: {} is unchanged; the map taught until then is in {}", staged_->path().string(),
                 staged_->staging_path().string());
    staged_.reset();
  }

  py::dict Statistics() const {
    const TeachStatistics& stats = teacher_->statistics();
    py::dict by_reason;
    for (int r = 0; r < static_cast<int>(stats.key_images_by_reason.size()); ++r) {
      by_reason[KeyImageReasonName(static_cast<KeyImageReason>(r))] = stats.key_images_by_reason[r];
    }
    py::list rejected;
    for (const RejectedLink& link : stats.rejected_links) {
      py::dict entry;
      entry["kind"] = link.kind;
      entry["node_from"] = link.from;
      entry["node_to"] = link.to;
      entry["frame_from"] = link.from_frame;
      entry["frame_to"] = link.to_frame;
      entry["inliers"] = link.inliers;
      entry["trackable"] = link.trackable;
      entry["sigma_p"] = link.sigma_p;
      entry["reason"] = link.reason;
      rejected.append(entry);
    }
    py::dict result;
    result["frames"] = stats.frames;
    result["key_images"] = stats.key_images;
    result["key_images_by_reason"] = by_reason;
    result["gaps_recovered"] = stats.gaps_recovered;
    result["gaps_unrecovered"] = stats.gaps_unrecovered;
    result["loop_closed"] = stats.loop_closed;
    result["rejected_links"] = rejected;
    result["nodes"] = teacher_->map().nodes().size();
    result["arcs"] = teacher_->map().arcs().size();
    return result;
  }

  double r_p() const { return teacher_->sigma_p_threshold_px(); }
  bool finished() const { return finished_; }
  const CameraModel& camera() const { return *camera_; }

 private:
  void CheckOpen() const {
    if (finished_) throw std::runtime_error("the teach has finished: its map is written");
    if (!staged_) throw std::runtime_error("the teach was abandoned");
  }

  std::unique_ptr<CameraModel> camera_;
  std::unique_ptr<StagedMap> staged_;
  std::unique_ptr<Teacher> teacher_;
  size_t next_index_ = 0;
  bool finished_ = false;
  std::mutex mutex_;  // one call at a time (the GIL is released while a frame is taught)
};

}  // namespace

void BindTeacher(py::module_& module) {
  py::class_<PythonTeacher>(
      module, "Teacher",
      "Teach: builds a map from frames given one at a time (Segvic 2009 §5.1) and writes it as `retrace teach`\n"
      "does: the map is built in PATH.incomplete (one writer at a time: PATH.lock) and moved onto PATH only by\n"
      "finish(), so an error or an abandoned teach leaves an existing PATH untouched.\n\n"
      "    with retrace.Teacher('route.db', camera) as teacher:\n"
      "        for image in images:\n"
      "            teacher.add_frame(image)\n"
      "    # leaving the block finishes the teach (or abandons it on an exception)\n\n"
      "The GIL is released while a frame is taught.")
      .def(py::init([](const py::object& path, const CameraModel& camera, int width, std::optional<std::string> source,
                       bool overwrite, const std::string& method, double r_p, int min_features,
                       double min_features_fraction, double max_residual, int max_corners, int matching_interval,
                       bool loop_closing, bool gap_recovery, const std::string& image_format, int image_quality,
                       double camera_height) {
             if (method != "tracking" && method != "matching") {
               throw py::value_error("method: expected 'tracking' or 'matching', got '" + method + "'");
             }
             if (width < 0) throw py::value_error("width: must be positive (0 = the camera's)");
             if (!(camera_height >= 0.0 && camera_height <= 100.0)) {
               throw py::value_error("camera_height: must be in [0, 100] m (0 = not given)");
             }
             TeachOptions options;
             options.method = method == "matching" ? TeachOptions::Method::kMatching : TeachOptions::Method::kTracking;
             options.max_sigma_p_px = r_p;
             options.min_features = min_features;
             options.min_features_fraction = min_features_fraction;
             options.max_residual = max_residual;
             options.max_corners = max_corners;
             options.matching_interval = matching_interval;
             options.close_loop = loop_closing;
             options.recover_gaps = gap_recovery;
             MapDatabaseOptions storage;
             storage.image_format = image_format;
             storage.image_quality = image_quality;
             return std::make_unique<PythonTeacher>(PathFromObject(path, "path"), camera, width, source, overwrite,
                                                    options, storage, method, camera_height);
           }),
           py::arg("path"), py::arg("camera"), py::kw_only(), py::arg("width") = 0, py::arg("source") = py::none(),
           py::arg("overwrite") = false, py::arg("method") = "tracking", py::arg("r_p") = TeachOptions().max_sigma_p_px,
           py::arg("min_features") = TeachOptions().min_features,
           py::arg("min_features_fraction") = TeachOptions().min_features_fraction,
           py::arg("max_residual") = TeachOptions().max_residual, py::arg("max_corners") = TeachOptions().max_corners,
           py::arg("matching_interval") = TeachOptions().matching_interval, py::arg("loop_closing") = true,
           py::arg("gap_recovery") = true, py::arg("image_format") = MapDatabaseOptions().image_format,
           py::arg("image_quality") = MapDatabaseOptions().image_quality, py::arg("camera_height") = 0.0,
           "Starts teaching a map into the file `path` with frames of `camera` (retrace.Camera).\n\n"
           "width: work on frames resized to this width (--width; 0 = the camera's).\n"
           "source: recorded in the map as its teach sequence (source_sequence), e.g. the folder of the frames.\n"
           "overwrite: replace an existing retrace map at `path` (only when finish() succeeds).\n"
           "The other keywords are those of `retrace teach` (--method, --r-p, --min-features,\n"
           "--min-features-fraction, --max-residual, --max-corners, --matching-interval; loop_closing=False is\n"
           "--no-loop-closing, gap_recovery=False --no-gap-recovery, --image-format, --image-quality,\n"
           "camera_height --camera-height: the camera's height above the ground in metres, stored for repeat's\n"
           "metric path; 0 = not given).\n"
           "Raises retrace.InputError when `path` exists (without overwrite), is not a retrace map, or is being\n"
           "written by another teach.")
      .def("add_frame", &PythonTeacher::AddFrame, py::arg("image"), py::arg("timestamp") = py::none(),
           py::arg("name") = py::none(),
           "Teaches the next frame: a numpy uint8 image, gray (H, W) or BGR (H, W, 3), of the camera's size, or a\n"
           "retrace.Frame. Frames are numbered 0, 1, 2, ... (Node.source_frame) unless a retrace.Frame brings its\n"
           "index; name and timestamp are stored with key-images.")
      .def("finish", &PythonTeacher::Finish,
           "Registers the last frame as a key-image, closes the loop when it can, and moves the map onto its path.\n"
           "Call once, after the last frame; the map can then be opened with retrace.Map(path).")
      .def("abandon", &PythonTeacher::Abandon,
           "Gives up without writing the map: its path stays as it was, what was taught stays in PATH.incomplete.")
      .def_property_readonly("statistics", &PythonTeacher::Statistics,
                             "What teach did so far: frames, key_images (by reason), gaps, loop_closed, the links it "
                             "rejected and why, nodes and arcs.")
      .def_property_readonly("r_p", &PythonTeacher::r_p, "r_p in pixels of the frames (scaled to their width).")
      .def_property_readonly("finished", &PythonTeacher::finished, "Whether finish() wrote the map.")
      .def_property_readonly(
          "camera", [](const PythonTeacher& t) { return std::shared_ptr<CameraModel>(t.camera().Clone()); },
          "The camera of the frames as taught (after width).")
      .def("__enter__", [](py::object self) { return self; })
      .def(
          "__exit__",
          [](PythonTeacher& self, const py::object& type, const py::object&, const py::object&) {
            if (type.is_none()) {
              if (!self.finished()) self.Finish();
            } else {
              self.Abandon();
            }
            return false;
          },
          "Finishes the teach when the block ended normally, abandons it on an exception.");
}

}  // namespace retrace::python
