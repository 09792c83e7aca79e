// retrace.Simulator: a scenario's drive through the procedural town (sim/simulator.h) rendered frame by frame into
// numpy images with their ground-truth poses, or recorded to a folder as `retrace sim render` does.

#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include <fmt/format.h>
#include <pybind11/stl.h>

#include "python_common.h"
#include "retrace/sim/recording.h"
#include "retrace/sim/scenario.h"
#include "retrace/sim/scenario_io.h"
#include "retrace/sim/simulator.h"
#include "retrace/util/error.h"

namespace retrace::python {
namespace {

// One rendered frame of the autopilot's drive.
struct PythonSimFrame {
  int index = 0;
  SimFrame frame;
};

class PythonSimulator {
 public:
  PythonSimulator(const std::optional<std::filesystem::path>& scenario_file, const std::string& variant,
                  const ScenarioOverrides& overrides) {
    if (variant != "teach" && variant != "repeat") {
      throw py::value_error("variant: expected 'teach' or 'repeat', got '" + variant + "'");
    }
    const std::string file = scenario_file ? scenario_file->string() : std::string();
    py::gil_scoped_release release;  // building the town takes a few hundred milliseconds
    Scenario scenario = file.empty() ? Scenario() : ReadScenario(file);
    // The same check and messages as `retrace sim render`'s options (ScenarioOverrides::Apply).
    if (const std::string bad = overrides.Apply(&scenario); !bad.empty()) {
      throw InputError(bad.rfind("--", 0) == 0 ? "" : file, bad);
    }
    simulator_ = std::make_unique<Simulator>(
        ApplyVariant(scenario, variant == "repeat" ? ScenarioVariant::kRepeat : ScenarioVariant::kTeach));
  }

  std::optional<PythonSimFrame> NextFrame() {
    py::gil_scoped_release release;
    const std::lock_guard<std::mutex> lock(mutex_);
    PythonSimFrame next;
    if (!simulator_->NextFrame(&next.frame)) return std::nullopt;
    next.index = frames_++;
    return next;
  }

  py::dict Record(const std::filesystem::path& out, const std::optional<std::filesystem::path>& contact_sheet,
                  int contact_sheet_every, bool progress) {
    const int max_frames = static_cast<int>(FindScenarioKeyRange("frames")->max);
    if (simulator_->ExpectedFrames() > max_frames) {
      throw InputError("", fmt::format("the route ({:.0f} m) takes about {} frames at {} Hz, more than {}: set "
                                       "frames or a shorter route",
                                       simulator_->route().length(), simulator_->ExpectedFrames(),
                                       simulator_->scenario().frame_rate, max_frames));
    }
    RecordOptions options;
    options.progress = progress;
    if (contact_sheet) options.contact_sheet = *contact_sheet;
    options.contact_sheet_every = std::max(1, contact_sheet_every);
    RecordSummary summary;
    {
      py::gil_scoped_release release;
      const std::lock_guard<std::mutex> lock(mutex_);
      summary = RecordSequence(simulator_.get(), out, options);
    }
    py::dict result;
    result["frames"] = summary.frames;
    result["frames_requested"] = summary.frames_requested;
    result["stopped_at_route_end"] = summary.stopped_at_route_end;
    result["route_length_m"] = summary.route_length_m;
    result["driven_m"] = summary.driven_m;
    result["seconds"] = summary.seconds;
    return result;
  }

  cv::Mat RenderAt(const Rigid3d& world_from_cam, double time, uint64_t noise_seed) {
    py::gil_scoped_release release;
    const std::lock_guard<std::mutex> lock(mutex_);
    return simulator_->RenderAt(world_from_cam, time, noise_seed);
  }

  const Simulator& simulator() const { return *simulator_; }

 private:
  std::unique_ptr<Simulator> simulator_;
  int frames_ = 0;
  std::mutex mutex_;  // one render at a time (the GIL is released while rendering)
};

Rigid3d RigidFromMatrix(const py::handle& object) {
  const auto matrix = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(object);
  if (!matrix || matrix.ndim() != 2 || !(matrix.shape(0) == 3 || matrix.shape(0) == 4) || matrix.shape(1) != 4) {
    throw py::value_error("world_from_cam: expected a 4x4 (or 3x4) matrix [R t]");
  }
  Rigid3d transform;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) transform.rotation(r, c) = matrix.at(r, c);
    transform.translation(r) = matrix.at(r, 3);
  }
  return transform;
}

}  // namespace

void BindSimulator(py::module_& module) {
  py::class_<PythonSimFrame>(
      module, "SimFrame",
      "A frame rendered by the simulator with its ground truth. Poses are world_from_cam in the\n"
      "simulator's world frame (a level camera on the ground at the route's start: x right, y\n"
      "down, z forward), as `retrace sim render` writes them to poses.txt.")
      .def_readonly("index", &PythonSimFrame::index, "Frame number, from 0.")
      .def_property_readonly(
          "image", [](const PythonSimFrame& f) { return ArrayFromImage(f.frame.image); },
          "The image, numpy uint8 (H, W) gray, or (H, W, 3) BGR when the scenario's sensor.color is set.")
      .def_property_readonly(
          "timestamp", [](const PythonSimFrame& f) { return f.frame.timestamp; }, "Seconds since the first frame.")
      .def_property_readonly(
          "world_from_cam", [](const PythonSimFrame& f) { return MatrixFromRigid(f.frame.world_from_cam); },
          "Ground-truth camera pose, 4x4 [R t; 0 1] mapping camera coordinates to the world frame.")
      .def_property_readonly(
          "progress", [](const PythonSimFrame& f) { return f.frame.progress; }, "Metres driven along the route.")
      .def_property_readonly(
          "speed", [](const PythonSimFrame& f) { return f.frame.vehicle.speed; }, "The car's speed, m/s.")
      .def("__repr__", [](const PythonSimFrame& f) {
        return fmt::format("<retrace.SimFrame {}: t = {:.2f} s, {:.1f} m along the route>", f.index, f.frame.timestamp,
                           f.frame.progress);
      });

  py::class_<PythonSimulator>(
      module, "Simulator",
      "The simulator: a scenario's drive through the built-in procedural town (or a scene file), rendered frame\n"
      "by frame with ground truth. The same drives as `retrace sim render`: the same scenario and options give the\n"
      "same images and poses.\n\n"
      "    simulator = retrace.Simulator(frames=100, width=320, height=240)\n"
      "    for frame in simulator:          # retrace.SimFrame: image, timestamp, world_from_cam\n"
      "        ...\n\n"
      "The GIL is released while a frame is rendered.")
      .def(py::init([](const py::object& scenario, const std::string& variant, std::optional<int> frames,
                       std::optional<int> width, std::optional<int> height, std::optional<int64_t> seed,
                       std::optional<std::string> route, std::optional<int> segments, std::optional<double> speed,
                       std::optional<double> frame_rate, std::optional<int> pedestrians,
                       std::optional<std::string> lighting, std::optional<std::string> repeat_lighting,
                       std::optional<double> lateral_offset, std::optional<int> threads) {
             ScenarioOverrides overrides;
             overrides.frames = frames;
             overrides.width = width;
             overrides.height = height;
             overrides.seed = seed;
             overrides.route = route;
             overrides.segments = segments;
             overrides.max_speed = speed;
             overrides.frame_rate = frame_rate;
             overrides.pedestrians = pedestrians;
             overrides.lighting = lighting;
             overrides.repeat_lighting = repeat_lighting;
             overrides.lateral_offset = lateral_offset;
             overrides.threads = threads;
             std::optional<std::filesystem::path> file;
             if (!scenario.is_none()) file = PathFromObject(scenario, "scenario");
             return std::make_unique<PythonSimulator>(file, variant, overrides);
           }),
           py::arg("scenario") = py::none(), py::arg("variant") = "teach", py::kw_only(),
           py::arg("frames") = py::none(), py::arg("width") = py::none(), py::arg("height") = py::none(),
           py::arg("seed") = py::none(), py::arg("route") = py::none(), py::arg("segments") = py::none(),
           py::arg("speed") = py::none(), py::arg("frame_rate") = py::none(), py::arg("pedestrians") = py::none(),
           py::arg("lighting") = py::none(), py::arg("repeat_lighting") = py::none(),
           py::arg("lateral_offset") = py::none(), py::arg("threads") = py::none(),
           "Builds the scenario's world (a few hundred milliseconds) with the car at the route's start.\n\n"
           "scenario: a scenario file (YAML/JSON, `retrace sim example-scenario` documents every key); default the\n"
           "built-in scenario. variant: 'teach', or 'repeat' (other sun and exposure, 1 m lateral offset, wobble,\n"
           "pedestrians elsewhere). The keywords override the scenario as the options of `retrace sim render` do\n"
           "(--frames: 0 = the whole route, --width, --height, --seed, --route, --segments, --speed, --frame-rate,\n"
           "--pedestrians, --lighting, --repeat-lighting, --lateral-offset, --threads), with the same ranges and\n"
           "one-line errors (retrace.InputError, naming the option as the command line spells it).")
      .def("next_frame", &PythonSimulator::NextFrame,
           "Renders the current view, then drives one frame period along the route. Returns a retrace.SimFrame,\n"
           "or None when the route is finished or the scenario's frame count is reached.")
      .def("__iter__", [](py::object self) { return self; })
      .def("__next__",
           [](PythonSimulator& self) {
             std::optional<PythonSimFrame> frame = self.NextFrame();
             if (!frame) throw py::stop_iteration();
             return *frame;
           })
      .def(
          "record",
          [](PythonSimulator& self, const py::object& out, const py::object& contact_sheet, int contact_sheet_every,
             bool progress) {
            std::optional<std::filesystem::path> sheet;
            if (!contact_sheet.is_none()) sheet = PathFromObject(contact_sheet, "contact_sheet");
            return self.Record(PathFromObject(out, "out"), sheet, contact_sheet_every, progress);
          },
          py::arg("out"), py::kw_only(), py::arg("contact_sheet") = py::none(), py::arg("contact_sheet_every") = 10,
          py::arg("progress") = false,
          "Drives the rest of the route (or up to the frame count) and writes it to the folder `out` as `retrace sim\n"
          "render --out` does: KITTI layout (image_0/*.png, times.txt, poses.txt, calib.txt) plus camera.yaml and\n"
          "scenario.yaml. Returns a summary: frames, frames_requested, stopped_at_route_end, route_length_m,\n"
          "driven_m, seconds.")
      .def(
          "render_at",
          [](PythonSimulator& self, const py::object& world_from_cam, double time, uint64_t noise_seed) {
            return ArrayFromImage(self.RenderAt(RigidFromMatrix(world_from_cam), time, noise_seed));
          },
          py::arg("world_from_cam"), py::arg("time") = 0.0, py::arg("noise_seed") = 0,
          "Renders the world at `time` (seconds) from any camera pose world_from_cam (4x4 or 3x4).")
      .def_property_readonly(
          "camera",
          [](const PythonSimulator& s) { return std::shared_ptr<CameraModel>(s.simulator().camera().Clone()); },
          "The camera of the rendered frames (retrace.Camera).")
      .def_property_readonly(
          "expected_frames", [](const PythonSimulator& s) { return s.simulator().ExpectedFrames(); },
          "Frames the drive will give: the frame count, or the whole route's when it ends first (or frames = 0).")
      .def_property_readonly(
          "route_length", [](const PythonSimulator& s) { return s.simulator().route().length(); },
          "Length of the route, metres.")
      .def_property_readonly(
          "route_finished", [](const PythonSimulator& s) { return s.simulator().RouteFinished(); },
          "Whether the drive stopped at the route's end.")
      .def_property_readonly(
          "scenario_yaml", [](const PythonSimulator& s) { return ScenarioToYaml(s.simulator().scenario()); },
          "The effective scenario (after the variant and the overrides) as YAML, to reproduce the drive.");

  module.def(
      "example_scenario", []() { return ScenarioToYaml(Scenario()); },
      "The built-in scenario as YAML with a comment on every key (`retrace sim example-scenario`).");
}

}  // namespace retrace::python
