// retrace.Camera: a calibration read from the files the command line's --camera reads (camera/camera_io.h).

#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <string>

#include <pybind11/stl.h>

#include "python_common.h"
#include "retrace/camera/camera_checks.h"
#include "retrace/camera/camera_io.h"
#include "retrace/camera/camera_model.h"

namespace retrace::python {
namespace {

std::optional<cv::Size> SizeFromTuple(const std::optional<std::pair<int, int>>& size) {
  if (!size) return std::nullopt;
  return cv::Size(size->first, size->second);
}

// Points as an (N, dims) array of doubles from anything numpy reads as (N, dims) or (dims,).
py::array_t<double> PointsArray(const py::handle& object, int dims, const char* what) {
  auto points = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(object);
  if (!points ||
      !((points.ndim() == 2 && points.shape(1) == dims) || (points.ndim() == 1 && points.shape(0) == dims))) {
    throw py::value_error(std::string(what) + ": expected an array of shape (N, " + std::to_string(dims) + ") or (" +
                          std::to_string(dims) + ",)");
  }
  return points;
}

}  // namespace

void BindCamera(py::module_& module) {
  py::class_<CameraModel, std::shared_ptr<CameraModel>> camera(
      module, "Camera",
      "A camera model: perspective (pinhole + radial-tangential distortion), unified (Mei 2007: fisheye,\n"
      "catadioptric) or equirectangular (360 x 180 degree panorama). Pixel (0, 0) is the centre of the top-left\n"
      "pixel; the camera frame has x right, y down, z forward.\n\n"
      "Made by Camera.read(path) (ROS camera_info / OpenCV YAML or XML, KITTI calib.txt, EuRoC sensor.yaml,\n"
      "retrace's own camera.yaml), Camera.from_yaml(text), Map.camera or Simulator.camera.");
  camera
      .def_static(
          "read",
          [](const py::object& path, std::optional<std::pair<int, int>> image_size, const std::string& camera) {
            return std::shared_ptr<CameraModel>(
                ReadCameraFile(PathFromObject(path, "path"), SizeFromTuple(image_size), camera));
          },
          py::arg("path"), py::arg("image_size") = py::none(), py::arg("camera") = "",
          "Reads a calibration file, recognised by its content (the readers of `retrace ... --camera`).\n"
          "image_size=(width, height) supplies the size a file lacks (KITTI calib.txt) and must agree with one it\n"
          "has. camera names one of a file that holds several (KITTI calib.txt: 'P0' to 'P3', Sequence's\n"
          "calibration_camera; '' the first). Raises retrace.InputError naming the file for a missing, unreadable or\n"
          "implausible calibration.")
      .def_static(
          "from_yaml",
          [](const std::string& text, const std::string& source, std::optional<std::pair<int, int>> image_size) {
            return std::shared_ptr<CameraModel>(ParseCameraText(text, source, SizeFromTuple(image_size)));
          },
          py::arg("text"), py::arg("source") = "camera", py::arg("image_size") = py::none(),
          "Parses calibration text in any format Camera.read accepts; `source` names it in errors.")
      .def_property_readonly("model", &CameraModel::model_name,
                             "The model's name: 'perspective', 'unified' or 'equirectangular'.")
      .def_property_readonly("width", &CameraModel::width, "Image width in pixels.")
      .def_property_readonly("height", &CameraModel::height, "Image height in pixels.")
      .def_property_readonly("focal_length", &CameraModel::FocalLength,
                             "Pixels per radian of viewing angle near the image centre.")
      .def(
          "scaled",
          [](const CameraModel& self, double factor) {
            if (!(factor > 0.0 && std::isfinite(factor))) throw py::value_error("factor: must be positive");
            return std::shared_ptr<CameraModel>(self.Scaled(factor));
          },
          py::arg("factor"), "The same camera for images resized by `factor` (e.g. 0.5 for half the width).")
      .def(
          "project",
          [](const CameraModel& self, const py::object& points_in_cam) {
            const auto points = PointsArray(points_in_cam, 3, "points_in_cam");
            const py::ssize_t n = points.size() / 3;
            py::array_t<double> pixels(points.ndim() == 1 ? std::vector<py::ssize_t>{2}
                                                          : std::vector<py::ssize_t>{n, 2});
            const double* in = points.data();
            double* out = pixels.mutable_data();
            for (py::ssize_t i = 0; i < n; ++i) {
              Vector2d pixel;
              const bool ok = self.Project(Vector3d(in[3 * i], in[3 * i + 1], in[3 * i + 2]), &pixel);
              out[2 * i] = ok ? pixel.x() : std::numeric_limits<double>::quiet_NaN();
              out[2 * i + 1] = ok ? pixel.y() : std::numeric_limits<double>::quiet_NaN();
            }
            return pixels;
          },
          py::arg("points_in_cam"),
          "Pixels (N, 2) of points (N, 3) given in the camera frame; NaN where a point has no image (behind a\n"
          "perspective camera). Pixels may lie outside the image.")
      .def(
          "unproject",
          [](const CameraModel& self, const py::object& pixels_in) {
            const auto pixels = PointsArray(pixels_in, 2, "pixels");
            const py::ssize_t n = pixels.size() / 2;
            py::array_t<double> bearings(pixels.ndim() == 1 ? std::vector<py::ssize_t>{3}
                                                            : std::vector<py::ssize_t>{n, 3});
            const double* in = pixels.data();
            double* out = bearings.mutable_data();
            for (py::ssize_t i = 0; i < n; ++i) {
              Vector3d bearing;
              const bool ok = self.Unproject(Vector2d(in[2 * i], in[2 * i + 1]), &bearing);
              for (int k = 0; k < 3; ++k) out[3 * i + k] = ok ? bearing(k) : std::numeric_limits<double>::quiet_NaN();
            }
            return bearings;
          },
          py::arg("pixels"), "Unit bearing vectors (N, 3) of the rays through pixels (N, 2); NaN where none.")
      .def(
          "to_yaml", [](const CameraModel& self) { return CameraToYaml(self); },
          "The calibration as retrace writes it (ROS camera_info YAML, plus camera_model and xi when needed).")
      .def(
          "write",
          [](const CameraModel& self, const py::object& path) { WriteCameraFile(self, PathFromObject(path, "path")); },
          py::arg("path"), "Writes the calibration as to_yaml() gives it.")
      .def("__repr__", [](const CameraModel& self) {
        return "<retrace.Camera " + self.model_name() + " " + std::to_string(self.width()) + "x" +
               std::to_string(self.height()) + ": " + DescribeCameraIntrinsics(self) + ">";
      });

  module.def(
      "load_camera",
      [](const py::object& path, std::optional<std::pair<int, int>> image_size) {
        return std::shared_ptr<CameraModel>(ReadCameraFile(PathFromObject(path, "path"), SizeFromTuple(image_size)));
      },
      py::arg("path"), py::arg("image_size") = py::none(), "Camera.read(path, image_size): a calibration file.");
}

}  // namespace retrace::python
