// retrace.Sequence and retrace.Frame: image sequences read as the command line's --sequence reads them
// (dataset/sequence.h: a folder of images, a video, the KITTI or EuRoC layout), frames as 8-bit gray numpy images.

#include <memory>
#include <optional>
#include <string>

#include <fmt/format.h>
#include <pybind11/stl.h>

#include "python_common.h"
#include "retrace/dataset/sequence.h"

namespace retrace::python {

void BindSequence(py::module_& module) {
  py::class_<Frame>(module, "Frame",
                    "A frame of a sequence: its position, name, timestamp and 8-bit gray image. Localizer.process\n"
                    "and Teacher.add_frame take one as they take an image, and use its index, name and timestamp.")
      .def(py::init([](const py::handle& image, size_t index, double timestamp, std::optional<std::string> name) {
             Frame frame;
             frame.image = GrayImageFromArray(image, "image");
             frame.index = frame.source_index = index;
             frame.timestamp = timestamp;
             frame.name = name ? *name : fmt::format("frame_{:06d}", index);
             return frame;
           }),
           py::arg("image"), py::arg("index") = 0, py::arg("timestamp") = 0.0, py::arg("name") = py::none(),
           "A frame from a numpy image (gray, or BGR converted to gray); name defaults to 'frame_NNNNNN'.")
      .def_readonly("index", &Frame::index, "Position in the sequence it was read from (after every/offset).")
      .def_readonly("source_index", &Frame::source_index, "Position in the original sequence.")
      .def_readonly("name", &Frame::name, "File name without folder (e.g. '000042.png').")
      .def_readonly("timestamp", &Frame::timestamp, "Seconds.")
      .def_property_readonly(
          "image", [](const Frame& frame) { return ArrayFromImage(frame.image); },
          "The image, numpy uint8 (H, W) (a copy).")
      .def("__repr__", [](const Frame& frame) {
        return fmt::format("<retrace.Frame {} ({}), t = {:.3f} s, {}x{}>", frame.index, frame.name, frame.timestamp,
                           frame.image.cols, frame.image.rows);
      });

  py::class_<Sequence, std::unique_ptr<Sequence>>(
      module, "Sequence",
      "An image sequence, read as `retrace teach/repeat --sequence PATH` read it: a folder of images (optional\n"
      "times.txt), a video file, the KITTI odometry layout or the EuRoC layout. Iterating yields retrace.Frame\n"
      "objects (8-bit gray); unreadable frame files are skipped with a warning, a frame of another size than the\n"
      "first raises retrace.InputError naming its file.")
      .def(py::init([](const py::object& path, size_t every, size_t offset) {
             if (every < 1) throw py::value_error("every: must be at least 1");
             std::unique_ptr<Sequence> sequence = OpenSequence(PathFromObject(path, "path"));
             if (every > 1 || offset > 0) {
               sequence = std::make_unique<SubsampledSequence>(std::move(sequence), every, offset);
             }
             return sequence;
           }),
           py::arg("path"), py::arg("every") = 1, py::arg("offset") = 0,
           "Opens the sequence at `path`; every=k, offset=o keeps frames o, o + k, o + 2k, ... (as --every, "
           "--offset).")
      .def("__len__", &Sequence::size, "Frames the sequence lists (0 when unknown, e.g. some videos).")
      .def(
          "__iter__",
          [](Sequence& sequence) -> Sequence& {
            sequence.Rewind();
            return sequence;
          },
          "Iterates over the frames from the first one.")
      .def("__next__",
           [](Sequence& sequence) {
             // The GIL stays held while a frame is read: one reader at a time (a Sequence is not thread-safe).
             std::optional<Frame> frame = sequence.Next();
             if (!frame) throw py::stop_iteration();
             return *frame;
           })
      .def_property_readonly("layout", &Sequence::layout, "'folder', 'video', 'kitti' or 'euroc'.")
      .def_property_readonly(
          "path", [](const Sequence& s) { return s.path().string(); }, "The sequence's root as detected.")
      .def_property_readonly(
          "image_size",
          [](Sequence& s) {
            const cv::Size size = s.image_size();
            return std::make_pair(size.width, size.height);
          },
          "(width, height) of the first readable frame.")
      .def_property_readonly(
          "calibration_file",
          [](const Sequence& s) -> std::optional<std::string> {
            const auto file = s.calibration_file();
            return file ? std::optional<std::string>(file->string()) : std::nullopt;
          },
          "The calibration file that belongs to the sequence (KITTI camera.yaml or calib.txt, EuRoC sensor.yaml, "
          "a folder's camera.yaml), or None.")
      .def_property_readonly("calibration_camera", &Sequence::calibration_camera,
                             "Which camera of the calibration file the frames come from (KITTI: 'P0' for image_0 "
                             "... 'P3' for image_3), '' for a file of one camera; give it to Camera.read.")
      .def_property_readonly(
          "ground_truth_file",
          [](const Sequence& s) -> std::optional<std::string> {
            const auto file = s.ground_truth_file();
            return file ? std::optional<std::string>(file->string()) : std::nullopt;
          },
          "The ground-truth trajectory file (KITTI poses.txt, EuRoC state_groundtruth_estimate0/data.csv), or None.")
      .def_property_readonly("skipped", &Sequence::skipped, "Names of the frames found unreadable so far.")
      .def("__repr__", [](Sequence& s) {
        return fmt::format("<retrace.Sequence {} ({}, {} frames)>", s.path().string(), s.layout(), s.size());
      });
}

}  // namespace retrace::python
