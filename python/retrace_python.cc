// The Python module `retrace`: retrace's maps, cameras, Localizer, Teacher and simulator for numpy images.
//
//   import retrace
//   localizer = retrace.Localizer("route.db")
//   result = localizer.process(gray_image)      # one frame: result.state, result.arc, result.steering, ...
//
// This file holds the module itself, the translation of retrace's errors into Python exceptions and the image
// conversions every part uses (python_common.h); each part of the API has its own file: python_camera.cc,
// python_map.cc, python_repeat.cc (Localizer), python_teach.cc (Teacher), python_sim.cc (Simulator).

#include <cstring>
#include <exception>
#include <filesystem>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <opencv2/core.hpp>
#include <spdlog/spdlog.h>

#include "python_common.h"
#include "retrace/image/image_utils.h"
#include "retrace/util/error.h"
#include "retrace/util/error_message.h"
#include "retrace/util/version.h"

namespace retrace::python {

cv::Mat GrayImageFromArray(const py::handle& object, const std::string& what) {
  if (!py::isinstance<py::array>(object)) {
    throw py::type_error(fmt::format("{}: expected a numpy array, got {}", what,
                                     py::str(py::type::of(object).attr("__name__")).cast<std::string>()));
  }
  const auto array = py::reinterpret_borrow<py::array>(object);
  const auto shape = [&] {
    std::string text;
    for (py::ssize_t d = 0; d < array.ndim(); ++d) text += (d ? ", " : "") + std::to_string(array.shape(d));
    return "(" + text + (array.ndim() == 1 ? ",)" : ")");
  };
  if (!array.dtype().is(py::dtype::of<uint8_t>())) {
    throw py::value_error(fmt::format("{}: expected dtype uint8, got {} (shape {})", what,
                                      py::str(array.dtype()).cast<std::string>(), shape()));
  }
  const bool gray = array.ndim() == 2;
  const bool colour = array.ndim() == 3 && (array.shape(2) == 1 || array.shape(2) == 3 || array.shape(2) == 4);
  if (!(gray || colour) || array.size() == 0) {
    throw py::value_error(
        fmt::format("{}: expected a non-empty gray image (H, W) or a BGR image (H, W, 3), got "
                    "shape {}",
                    what, shape()));
  }
  // A C-contiguous view (a copy when the array is strided, e.g. a crop), wrapped without copying, then converted.
  const auto contiguous = py::array_t<uint8_t, py::array::c_style>::ensure(array);
  const int channels = gray ? 1 : static_cast<int>(array.shape(2));
  const cv::Mat view(static_cast<int>(array.shape(0)), static_cast<int>(array.shape(1)), CV_8UC(channels),
                     const_cast<uint8_t*>(contiguous.data()));
  return channels == 1 ? view.clone() : ToGray8(view);
}

Frame FrameFromObject(const py::handle& object, size_t index, std::optional<double> timestamp,
                      std::optional<std::string> name, const std::string& what) {
  if (py::isinstance<Frame>(object)) {
    if (timestamp || name) throw py::value_error(what + ": a retrace.Frame has its own timestamp and name");
    return object.cast<Frame>();
  }
  Frame frame;
  frame.image = GrayImageFromArray(object, what);
  frame.index = frame.source_index = index;
  frame.timestamp = timestamp ? *timestamp : static_cast<double>(index);
  frame.name = name ? *name : fmt::format("frame_{:06d}", index);
  return frame;
}

py::array_t<uint8_t> ArrayFromImage(const cv::Mat& image) {
  CV_Assert(image.depth() == CV_8U && (image.channels() == 1 || image.channels() == 3));
  const cv::Mat continuous = image.isContinuous() ? image : image.clone();
  std::vector<py::ssize_t> shape = {image.rows, image.cols};
  if (image.channels() == 3) shape.push_back(3);
  py::array_t<uint8_t> array(shape);
  std::memcpy(array.mutable_data(), continuous.data, continuous.total() * continuous.elemSize());
  return array;
}

py::array_t<double> MatrixFromRigid(const Rigid3d& transform) {
  py::array_t<double> matrix({4, 4});
  auto m = matrix.mutable_unchecked<2>();
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) {
      m(r, c) = r == 3 ? (c == 3 ? 1.0 : 0.0) : c == 3 ? transform.translation(r) : transform.rotation(r, c);
    }
  }
  return matrix;
}

std::filesystem::path PathFromObject(const py::handle& object, const std::string& what) {
  const py::object path = py::module_::import("os").attr("fspath")(object);  // TypeError for anything else
  if (!py::isinstance<py::str>(path)) throw py::type_error(what + ": expected a str path, got bytes");
  return std::filesystem::path(path.cast<std::string>());
}

namespace {

// retrace.InputError: bad input named by its source (a file, a frame), a ValueError. Kept alive for the process.
PyObject* input_error_type = nullptr;

void TranslateExceptions(std::exception_ptr exception) {
  try {
    if (exception) std::rethrow_exception(exception);
  } catch (const InputError& e) {
    const std::string message = OneLineMessage(e.what());
    py::object instance = py::reinterpret_borrow<py::object>(input_error_type)(message);
    instance.attr("source") = OneLineMessage(e.source());
    instance.attr("problem") = OneLineMessage(e.problem());
    PyErr_SetObject(input_error_type, instance.ptr());
  } catch (const std::filesystem::filesystem_error& e) {
    PyErr_SetString(PyExc_OSError, OneLineMessage(e.what()).c_str());
  }
}

}  // namespace
}  // namespace retrace::python

PYBIND11_MODULE(retrace, module) {
  using namespace retrace;
  using namespace retrace::python;
  module.doc() =
      "retrace: monocular visual teach-and-repeat navigation (Segvic et al., CVIU 2009).\n\n"
      "Map: a taught map file, read (nodes = key-images, arcs = two-view geometries).\n"
      "Camera: a calibration (the files the command line's --camera reads).\n"
      "Localizer: repeat, fed numpy images frame by frame; returns a FrameResult per frame.\n"
      "Teacher: teach, fed numpy images frame by frame; writes a map file as `retrace teach` does.\n"
      "Simulator: renders a scenario's drive (numpy images with ground-truth poses).\n\n"
      "Images are numpy uint8 arrays, gray (H, W) or BGR (H, W, 3). Bad input raises retrace.InputError (a\n"
      "ValueError) with the one-line message the command line prints.";
  module.attr("__version__") = Version();

  input_error_type = PyErr_NewExceptionWithDoc(
      "retrace.InputError",
      "Bad input to retrace (an unreadable or corrupt file, a frame of the wrong size, a bad scenario): the one-line\n"
      "message `retrace` prints after 'retrace: error: ', naming the file or frame at fault. Attributes: source\n"
      "(the file or input at fault, may be empty) and problem (what is wrong with it).",
      PyExc_ValueError, nullptr);
  module.attr("InputError") = py::handle(input_error_type);
  py::register_exception_translator(&TranslateExceptions);

  module.def(
      "set_log_level",
      [](const std::string& level) {
        const auto parsed = spdlog::level::from_str(level);
        if (parsed == spdlog::level::off && level != "off") {
          throw py::value_error("level: expected trace, debug, info, warning, error, critical or off, got '" + level +
                                "'");
        }
        spdlog::set_level(parsed);
      },
      py::arg("level"),
      "Sets how much retrace logs to stderr: 'trace', 'debug', 'info' (default), 'warning', 'error', 'critical' or\n"
      "'off'. Warnings name inputs retrace uses despite a fault (e.g. an incomplete map).");

  BindCamera(module);
  BindSequence(module);
  BindMap(module);
  BindLocalizer(module);
  BindTeacher(module);
  BindSimulator(module);
}
