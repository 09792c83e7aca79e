#pragma once

// Shared pieces of the Python bindings (module `retrace`, retrace_python.cc): numpy <-> OpenCV image conversion and
// the functions that add each part of the API to the module.
//
// Conventions of the whole module:
//  - images are numpy uint8 arrays: gray (H, W), or colour (H, W, 3) in OpenCV's BGR order (and (H, W, 4) BGRA),
//    converted to gray as the command line converts image files (image/image_utils.h ToGray8); images returned are
//    copies the caller owns;
//  - retrace's bad-input errors (retrace::InputError: an unreadable file, a corrupt map, a frame of the wrong size)
//    arrive as retrace.InputError, a ValueError, with the one-line message the command line prints after
//    "retrace: error: ";
//  - the GIL is released while C++ works on a frame (localize, teach, render), so other Python threads run; one
//    object is used by one thread at a time (a second caller waits).

#include <filesystem>
#include <optional>
#include <string>

#include <opencv2/core.hpp>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include "retrace/dataset/sequence.h"
#include "retrace/util/types.h"

namespace retrace::python {

namespace py = pybind11;

// The 8-bit gray image of a numpy array (see the conventions above), a copy independent of the array. `what` names
// the argument in the ValueError / TypeError raised for another dtype or shape.
cv::Mat GrayImageFromArray(const py::handle& array, const std::string& what);

// The frame given to Localizer.process / Teacher.add_frame: a retrace.Frame as it is, or a numpy image (`what` names
// it in errors) made a frame with this index, name "frame_NNNNNN" unless `name` is given, and `timestamp` (default:
// the index in seconds, as for a folder of images without times.txt).
Frame FrameFromObject(const py::handle& object, size_t index, std::optional<double> timestamp,
                      std::optional<std::string> name, const std::string& what);

// A numpy copy of an image (8-bit, 1 or 3 channels): (H, W) or (H, W, 3).
py::array_t<uint8_t> ArrayFromImage(const cv::Mat& image);

// A rigid transform as a 4x4 numpy matrix [R t; 0 0 0 1].
py::array_t<double> MatrixFromRigid(const Rigid3d& transform);

// A path argument: str or os.PathLike.
std::filesystem::path PathFromObject(const py::handle& object, const std::string& what);

void BindCamera(py::module_& module);
void BindSequence(py::module_& module);
void BindMap(py::module_& module);
void BindLocalizer(py::module_& module);
void BindTeacher(py::module_& module);
void BindSimulator(py::module_& module);

}  // namespace retrace::python
