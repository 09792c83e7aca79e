// retrace.Localizer and retrace.FrameResult: repeat (repeat/localizer.h), fed numpy images frame by frame as
// `retrace repeat` feeds the frames of a sequence.

#include <cmath>
#include <filesystem>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include <fmt/format.h>
#include <pybind11/stl.h>

#include "python_common.h"
#include "retrace/camera/camera_checks.h"
#include "retrace/image/image_utils.h"
#include "retrace/repeat/localizer.h"
#include "retrace/repeat/map_loading.h"
#include "retrace/util/error.h"

namespace retrace::python {
namespace {

// Two calibrations that image the same rays within this distance at the key-images' resolution are one camera (as
// `retrace repeat --camera` decides).
constexpr double kSameCameraPx = 1.0;

// The Localizer with the map it localizes in and the camera of its frames.
class PythonLocalizer {
 public:
  PythonLocalizer(const std::filesystem::path& map_path, std::shared_ptr<CameraModel> camera,
                  std::optional<arc_t> start_arc, const LocalizerOptions& options) {
    py::gil_scoped_release release;  // reading and checking the map
    std::string error;
    if (!options.Check(&error)) throw InputError("localizer options", error);
    loaded_ = LoadMapForLocalizer(map_path, options);
    const int key_width = loaded_.key_image_size.width;
    if (camera) {
      camera_ = camera->width() == key_width ? camera->Clone()
                                             : camera->Scaled(static_cast<double>(key_width) / camera->width());
      // The key-images were measured with the map's camera: another calibration is refused, not bent to fit.
      const CameraModel* map_camera = loaded_.camera.get();
      if (map_camera) {
        const double difference = map_camera->height() == camera_->height()
                                      ? CameraProjectionDifferencePx(*map_camera, *camera_)
                                      : std::numeric_limits<double>::infinity();
        if (!(difference <= kSameCameraPx) || camera_->model_name() != map_camera->model_name()) {
          throw InputError(
              "camera", fmt::format("differs from the map's camera ({} at the map's {} px width): {} "
                                    "{}x{} {} vs the map's {} {}x{} {}; omit camera to use the map's",
                                    std::isfinite(difference) ? fmt::format("{:.1f} px apart", difference)
                                                              : "another image or rays not imaged",
                                    key_width, camera_->model_name(), camera_->width(), camera_->height(),
                                    DescribeCameraIntrinsics(*camera_), map_camera->model_name(), map_camera->width(),
                                    map_camera->height(), DescribeCameraIntrinsics(*map_camera)));
        }
      }
    } else {
      if (!loaded_.camera) throw InputError(map_path.string(), "the map stores no camera; give camera=");
      camera_ = loaded_.camera->Clone();
    }
    localizer_ = std::make_unique<Localizer>(std::move(loaded_.map), *camera_, loaded_.options);
    if (start_arc) localizer_->SetStartArc(*start_arc);
  }

  FrameResult Process(const py::handle& image, std::optional<double> timestamp, std::optional<std::string> name) {
    Frame frame = FrameFromObject(image, next_index_, timestamp, name, "image");
    next_index_ = frame.index + 1;
    py::gil_scoped_release release;
    const std::lock_guard<std::mutex> lock(mutex_);
    // Frames of the camera's shape at another resolution are resized to the key-images' width, as `retrace repeat`
    // does; any other size is the Localizer's error (InputError naming the frame and both sizes).
    if (frame.image.cols != camera_->width()) {
      cv::Mat resized;
      ResizeToWidth(frame.image, camera_->width(), &resized);
      if (resized.rows == camera_->height()) frame.image = resized;
    }
    return localizer_->ProcessFrame(frame);
  }

  const CameraModel& camera() const { return *camera_; }
  const Localizer& localizer() const { return *localizer_; }

 private:
  MapForLocalizer loaded_;
  std::unique_ptr<CameraModel> camera_;
  std::unique_ptr<Localizer> localizer_;
  size_t next_index_ = 0;
  std::mutex mutex_;  // one frame at a time (the GIL is released while a frame is processed)
};

std::optional<double> Finite(double value) {
  return std::isfinite(value) ? std::optional<double>(value) : std::nullopt;
}

const char* RoleName(ArcRole role) {
  switch (role) {
    case ArcRole::kPrevious:
      return "previous";
    case ArcRole::kCurrent:
      return "current";
    case ArcRole::kNext:
      return "next";
  }
  return "?";
}

}  // namespace

void BindLocalizer(py::module_& module) {
  py::class_<PathPose>(module, "PathPose",
                       "Where the camera is relative to the taught path in metres (repeat/taught_path.h): known when\n"
                       "the camera's height above the ground is (given to teach or to the Localizer) and the frame's\n"
                       "absolute pose in the arc's reconstruction is usable.")
      .def_readonly("lateral_m", &PathPose::lateral_m,
                    "Signed distance from the taught path, m (positive to the right in the direction of travel), the "
                    "recent frames' combined.")
      .def_readonly("lateral_sigma_m", &PathPose::lateral_sigma_m, "Its standard deviation, m.")
      .def_readonly("frame_lateral_m", &PathPose::frame_lateral_m, "This frame's own distance from the path, m.")
      .def_readonly("frame_lateral_sigma_m", &PathPose::frame_lateral_sigma_m, "Its standard deviation, m.")
      .def_readonly("heading_sigma_rad", &PathPose::heading_sigma_rad, "The heading error's standard deviation, rad.")
      .def_readonly("along_sigma_m", &PathPose::along_sigma_m, "along_m's standard deviation, m.")
      .def_readonly("heading_per_lateral", &PathPose::heading_per_lateral,
                    "The pose's regression of its heading error on its lateral offset, rad/m (about -1 / depth of "
                    "its points; 0 unknown).")
      .def_readonly("heading_error_rad", &PathPose::heading_error_rad,
                    "The optical axis against the path's tangent, radians (positive to the right).")
      .def_readonly("along_m", &PathPose::along_m, "Distance along the path from node_from, m.")
      .def_readonly("to_next_m", &PathPose::to_next_m, "Distance along the path left to node_to, m.")
      .def_readonly("arc_length_m", &PathPose::arc_length_m, "The reported arc's length along the path, m.")
      .def_readonly("curvature", &PathPose::curvature,
                    "Curvature of the path at its nearest point, 1/m (positive to the left).")
      .def_readonly("curvature_ahead", &PathPose::curvature_ahead,
                    "The sharpest curvature from here to the end of the next arc, 1/m (with its sign).")
      .def_readonly("scale_sigma", &PathPose::scale_sigma, "Relative standard deviation of the arc's metric scale.")
      .def("__repr__", [](const PathPose& p) {
        return fmt::format(
            "<retrace.PathPose lateral {:+.3f} m (sigma {:.3f}), heading error {:+.4f} rad, {:.2f} m "
            "along>",
            p.lateral_m, p.lateral_sigma_m, p.heading_error_rad, p.along_m);
      });

  py::class_<FrameResult>(
      module, "FrameResult",
      "What the Localizer says about one frame (one row of `retrace repeat`'s run.csv). `state` is 'tracking' on\n"
      "arc `arc` (node_from -> node_to) only when the place belief is confident enough and the frame gave it\n"
      "evidence; otherwise 'lost' or 'relocalizing', with arc, node_from and node_to -1. Lost is an answer, never a\n"
      "confident wrong place.")
      .def_readonly("frame_index", &FrameResult::frame_index, "Index of the frame (Frame.index, or a counter).")
      .def_property_readonly(
          "state", [](const FrameResult& r) { return std::string(LocalizerStateName(r.state)); },
          "'tracking', 'lost' or 'relocalizing'.")
      .def_property_readonly(
          "tracking", [](const FrameResult& r) { return r.state == LocalizerState::kTracking; }, "state == 'tracking'.")
      .def_readonly("arc", &FrameResult::arc, "The current arc's id; -1 unless tracking.")
      .def_readonly("node_from", &FrameResult::node_from, "Its first key-image (node id); -1 unless tracking.")
      .def_readonly("node_to", &FrameResult::node_to, "Its second key-image (node id); -1 unless tracking.")
      .def_readonly("confidence", &FrameResult::confidence,
                    "The belief's probability that the camera is on the reported arc (in lost frames: on belief_arc).")
      .def_readonly("belief_arc", &FrameResult::belief_arc,
                    "The arc the belief finds most likely, reported or not (-1 before any evidence).")
      .def_readonly("evidence", &FrameResult::evidence, "Whether this frame gave the belief a placement it accepts.")
      .def_property_readonly(
          "position_on_arc",
          [](const FrameResult& r) {
            return r.position_valid ? std::optional<double>(r.position_on_arc) : std::nullopt;
          },
          "The belief's position along the arc (0 at node_from, 1 at node_to), or None when unknown.")
      .def_readonly("position_sigma", &FrameResult::position_sigma,
                    "Spread of the belief's position on the arc, arc lengths.")
      .def_property_readonly(
          "steering",
          [](const FrameResult& r) { return r.steering_valid ? std::optional<double>(r.steering) : std::nullopt; },
          "Steering command w of Segvic 2009 eq. (10), radians (w < 0 turns left), or None when not valid.")
      .def_property_readonly(
          "path", [](const FrameResult& r) { return r.path.valid ? std::optional<PathPose>(r.path) : std::nullopt; },
          "Where the camera is relative to the taught path in metres (retrace.PathPose), or None when unknown\n"
          "(no camera height, or no usable absolute pose in this frame).")
      .def_readonly("tracked", &FrameResult::tracked, "Features tracked after this frame (all arcs).")
      .def_property_readonly(
          "tracked_previous", [](const FrameResult& r) { return r.tracked_by_role[0]; },
          "... of them features of the previous arc.")
      .def_property_readonly(
          "tracked_current", [](const FrameResult& r) { return r.tracked_by_role[1]; }, "... of the current arc.")
      .def_property_readonly(
          "tracked_next", [](const FrameResult& r) { return r.tracked_by_role[2]; }, "... of the next arc.")
      .def_readonly("resumed", &FrameResult::resumed, "Features (re)started by prediction or bootstrap.")
      .def_readonly("rejected", &FrameResult::rejected, "Predictions refined but not accepted.")
      .def_readonly("dropped", &FrameResult::dropped, "Features lost by the tracker or the consistency check.")
      .def_readonly("drifted", &FrameResult::drifted, "... of which discontinued for drifting from their prediction.")
      .def_readonly("redefined", &FrameResult::redefined, "Features whose reference was redefined at a transition.")
      .def_readonly("sigma_p", &FrameResult::sigma_p,
                    "sigma_p of the geometry used for the current arc's transfer, px (-1: none).")
      .def_readonly("sigma_p_from", &FrameResult::sigma_p_from, "sigma_p of W_t:a, px (-1: none).")
      .def_readonly("sigma_p_to", &FrameResult::sigma_p_to, "sigma_p of W_t:b, px (-1: none).")
      .def_property_readonly(
          "position_via_from", [](const FrameResult& r) { return Finite(r.position_via_from); },
          "The position on the arc through W_t:a, or None.")
      .def_property_readonly(
          "position_via_to", [](const FrameResult& r) { return Finite(r.position_via_to); },
          "The position on the arc through W_t:b, or None.")
      .def_property_readonly(
          "position_via_pose", [](const FrameResult& r) { return Finite(r.position_via_pose); },
          "The position on the arc through the absolute pose in the arc's reconstruction, or None.")
      .def_readonly("sigma_p_pose", &FrameResult::sigma_p_pose, "sigma_p of that absolute pose, px (-1: none).")
      .def_readonly("pose_inliers", &FrameResult::pose_inliers, "Its inliers.")
      .def_readonly("transition", &FrameResult::transition,
                    "Arcs moved in this frame: +1 forward, -1 backward, +2 two arcs forward, ...")
      .def_readonly("bootstrapped", &FrameResult::bootstrapped,
                    "(Re)initialised by wide-baseline matching in this frame.")
      .def_readonly("key_images_matched", &FrameResult::key_images_matched,
                    "Key-images verified by wide-baseline matching in this frame.")
      .def_readonly("seconds", &FrameResult::seconds, "Processing time of this frame, seconds.")
      .def_property_readonly(
          "marks",
          [](const FrameResult& r) {
            py::list marks;
            for (const FeatureMark& mark : r.marks) {
              marks.append(py::make_tuple(mark.position.x(), mark.position.y(), RoleName(mark.role), mark.tracked));
            }
            return marks;
          },
          "Features drawn in overlays: (x, y, role, tracked) with role 'previous', 'current' or 'next'; tracked\n"
          "False for a rejected prediction.")
      .def("__repr__", [](const FrameResult& r) {
        if (r.state != LocalizerState::kTracking) {
          return fmt::format("<retrace.FrameResult frame {}: {}, confidence {:.3f}>", r.frame_index,
                             LocalizerStateName(r.state), r.confidence);
        }
        return fmt::format("<retrace.FrameResult frame {}: tracking arc {} ({} -> {}), confidence {:.3f}, {} tracked>",
                           r.frame_index, r.arc, r.node_from, r.node_to, r.confidence, r.tracked);
      });

  py::class_<PythonLocalizer>(
      module, "Localizer",
      "Repeat: localizes frames in a taught map one at a time, as from a live camera, and steers (Segvic 2009\n"
      "§5.2, §6.3). The same as `retrace repeat`: the same frames give the same states and arcs.\n\n"
      "    localizer = retrace.Localizer('route.db')\n"
      "    for frame in retrace.Sequence('drive/'):\n"
      "        result = localizer.process(frame)\n"
      "        print(result.state, result.arc, result.steering)\n\n"
      "The GIL is released while a frame is processed.")
      .def(py::init([](const py::object& map, std::shared_ptr<CameraModel> camera, std::optional<arc_t> start_arc,
                       double max_residual, double max_sigma_p, double steering_gain, int max_bad_frames,
                       double min_confidence, int max_cached_key_images, int retrieval_shortlist,
                       int start_retrieval_shortlist, bool absolute_pose,
                       bool redefine_references, double camera_height, bool sift_relocalization) {
             // A retrace.Map is localized in through its file: the Localizer reads the settings teach stored there.
             const py::object map_type = py::module_::import("retrace").attr("Map");
             const py::object path = py::isinstance(map, map_type) ? map.attr("path") : map;
             LocalizerOptions options;
             options.max_residual = max_residual;
             options.max_sigma_p_px = max_sigma_p;
             options.steering_gain = steering_gain;
             options.max_bad_frames = max_bad_frames;
             options.belief.min_confidence = min_confidence;
             options.max_cached_key_images = max_cached_key_images;
             options.retrieval_shortlist = retrieval_shortlist;
             options.start_retrieval_shortlist = start_retrieval_shortlist;
             options.place_by_absolute_pose = absolute_pose;
             options.redefine_references = redefine_references;
             options.path.camera_height = camera_height;
             options.binary_relocalization = !sift_relocalization;
             return std::make_unique<PythonLocalizer>(PathFromObject(path, "map"), std::move(camera), start_arc,
                                                      options);
           }),
           py::arg("map"), py::arg("camera") = py::none(), py::arg("start_arc") = py::none(), py::kw_only(),
           py::arg("max_residual") = LocalizerOptions().max_residual,
           py::arg("max_sigma_p") = LocalizerOptions().max_sigma_p_px,
           py::arg("steering_gain") = LocalizerOptions().steering_gain,
           py::arg("max_bad_frames") = LocalizerOptions().max_bad_frames,
           py::arg("min_confidence") = PlaceBeliefOptions().min_confidence,
           py::arg("max_cached_key_images") = LocalizerOptions().max_cached_key_images,
           py::arg("retrieval_shortlist") = LocalizerOptions().retrieval_shortlist,
           py::arg("start_retrieval_shortlist") = LocalizerOptions().start_retrieval_shortlist,
           py::arg("absolute_pose") = LocalizerOptions().place_by_absolute_pose,
           py::arg("redefine_references") = LocalizerOptions().redefine_references, py::arg("camera_height") = 0.0,
           py::arg("sift_relocalization") = !LocalizerOptions().binary_relocalization,
           "Opens the map (a path or a retrace.Map) for localizing, as `retrace repeat --map` does.\n\n"
           "camera: the frames' calibration (retrace.Camera); default the camera stored in the map. One that images\n"
           "the same rays more than 1 px away from the map's is refused.\n"
           "start_arc: bootstrap the first frame on this arc (--start-arc); default: found by retrieval.\n"
           "The keyword options are those of `retrace repeat` (--max-residual, --max-sigma-p, --steering-gain,\n"
           "--max-bad-frames, --min-confidence, --max-cached-key-images, --retrieval-shortlist,\n"
           "--start-retrieval-shortlist; absolute_pose=False\n"
           "is --no-absolute-pose, redefine_references=False --keep-references, camera_height --camera-height:\n"
           "the camera's height above the ground in metres for FrameResult.path; 0 = the one stored in the map;\n"
           "sift_relocalization=True is --sift: relocalize with SIFT extracted at run time, not the binary key-points\n"
           "the map stores).\n"
           "Raises retrace.InputError naming the file for a missing or damaged map, a camera that does not fit, a\n"
           "start arc the map does not have.")
      .def("process", &PythonLocalizer::Process, py::arg("image"), py::arg("timestamp") = py::none(),
           py::arg("name") = py::none(),
           "Localizes the next frame and returns its retrace.FrameResult.\n\n"
           "image: a numpy uint8 array, gray (H, W) or BGR (H, W, 3), of the camera's size (or its shape at\n"
           "another resolution: resized to the map's width, as `retrace repeat` does), or a retrace.Frame.\n"
           "Frames are numbered 0, 1, 2, ... unless a retrace.Frame brings its index. Another size raises\n"
           "retrace.InputError naming the frame; another dtype or shape ValueError.")
      .def_property_readonly(
          "state", [](const PythonLocalizer& l) { return std::string(LocalizerStateName(l.localizer().state())); },
          "The state after the last frame: 'tracking', 'lost' or 'relocalizing'.")
      .def_property_readonly(
          "camera", [](const PythonLocalizer& l) { return std::shared_ptr<CameraModel>(l.camera().Clone()); },
          "The camera the frames are localized with (at the key-images' width).")
      .def_property_readonly(
          "num_cached_key_images", [](const PythonLocalizer& l) { return l.localizer().NumCachedKeyImages(); },
          "Key-images whose derived data is in memory now (at most max_cached_key_images between frames).");
}

}  // namespace retrace::python
