// retrace.Map: a taught map file opened and read (map/map_database.h), with its nodes (key-images), arcs (two-view
// geometries) and relative scales, the camera and the metadata teach stored.

#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include <fmt/format.h>
#include <pybind11/stl.h>

#include "python_common.h"
#include "retrace/camera/camera_io.h"
#include "retrace/map/map.h"
#include "retrace/map/map_database.h"

namespace retrace::python {
namespace {

// A map read from its file. Node, Arc and Scale objects handed to Python point into it (and keep it alive).
struct OpenedMap {
  std::filesystem::path path;
  Map map;
  std::shared_ptr<CameraModel> camera;
  std::map<std::string, std::string> metadata;
  bool complete = true;
  int64_t image_bytes = 0;
};

std::unique_ptr<OpenedMap> OpenMap(const std::filesystem::path& path, bool load_images) {
  auto opened = std::make_unique<OpenedMap>();
  opened->path = path;
  py::gil_scoped_release release;
  const auto database = MapDatabase::Open(path);  // checks the whole file, as every command does
  opened->map = database->ReadMap(load_images);
  if (const auto yaml = database->ReadCameraYaml()) opened->camera = ParseCameraText(*yaml, path.string());
  opened->metadata = database->AllMetadata();
  opened->complete = database->complete();
  opened->image_bytes = database->ImageBytes();
  return opened;
}

// The elements of `items` as Python objects that refer into `owner` (kept alive while any of them lives).
template <typename T>
py::list ReferenceList(const std::vector<T>& items, const py::object& owner) {
  py::list list;
  for (const T& item : items) list.append(py::cast(&item, py::return_value_policy::reference_internal, owner));
  return list;
}

template <typename T>
py::list ReferenceList(const std::vector<const T*>& items, const py::object& owner) {
  py::list list;
  for (const T* item : items) list.append(py::cast(item, py::return_value_policy::reference_internal, owner));
  return list;
}

}  // namespace

void BindMap(py::module_& module) {
  py::class_<MapNode>(module, "Node",
                      "A node of the map: a key-image with the 2D positions of its features (Segvic 2009 §3.2).")
      .def_readonly("id", &MapNode::id, "Node id.")
      .def_readonly("source_frame", &MapNode::source_frame, "Index of the key-image in the teach sequence.")
      .def_readonly("image_name", &MapNode::image_name, "Name of the key-image's frame in the teach sequence.")
      .def_readonly("timestamp", &MapNode::timestamp, "Timestamp of the key-image's frame, seconds.")
      .def_property_readonly(
          "image",
          [](const MapNode& node) -> py::object {
            if (node.image.empty()) return py::none();
            return ArrayFromImage(node.image);
          },
          "The key-image, a numpy uint8 array (H, W) (a copy); None when the map was opened with "
          "load_images=False.")
      .def_property_readonly(
          "feature_ids",
          [](const MapNode& node) {
            py::array_t<int64_t> ids(static_cast<py::ssize_t>(node.features.size()));
            for (size_t i = 0; i < node.features.size(); ++i) ids.mutable_data()[i] = node.features[i].feature_id;
            return ids;
          },
          "Ids of the features seen in the key-image, int64 (N,); feature ids are unique over the map.")
      .def_property_readonly(
          "feature_positions",
          [](const MapNode& node) {
            py::array_t<double> positions({static_cast<py::ssize_t>(node.features.size()), py::ssize_t{2}});
            for (size_t i = 0; i < node.features.size(); ++i) {
              positions.mutable_data()[2 * i] = node.features[i].position.x();
              positions.mutable_data()[2 * i + 1] = node.features[i].position.y();
            }
            return positions;
          },
          "Pixel positions (N, 2) of those features in the key-image, in the order of feature_ids.")
      .def_property_readonly(
          "num_features", [](const MapNode& node) { return node.features.size(); }, "Features seen in the key-image.")
      .def_readonly("route", &MapNode::route,
                    "The drive that taught the key-image: 0 for the first, 1 for the first appended one (teach\n"
                    "--append), ...")
      .def("__repr__", [](const MapNode& node) {
        return fmt::format("<retrace.Node {}: frame {} ({}), {} features>", node.id, node.source_frame, node.image_name,
                           node.features.size());
      });

  py::class_<MapArc>(module, "Arc",
                     "An arc of the map from node_from to node_to: the two-view geometry W_k of the two key-images\n"
                     "(Segvic 2009 §3.2): the relative motion with a unit translation (the arc's unit of length), the\n"
                     "3D points of the features seen in both (the set M_k) and the geometry's quality sigma_p.")
      .def_readonly("id", &MapArc::id, "Arc id.")
      .def_readonly("node_from", &MapArc::from, "Node id of the arc's first key-image (a).")
      .def_readonly("node_to", &MapArc::to, "Node id of the arc's second key-image (b).")
      .def_readonly("kind", &MapArc::kind,
                    "How the arc was made: 'tracking', 'matching', 'gap' (wide-baseline matching across a tracking\n"
                    "failure), 'loop' (loop closing) or 'join'.")
      .def_readonly("sigma_p", &MapArc::sigma_p,
                    "sigma_p of the geometry, pixels: conservative reprojection error bound (Segvic 2009, eq. (6)).")
      .def_property_readonly("num_features", &MapArc::num_features, "|M_k|: features the arc reconstructs.")
      .def_property_readonly(
          "similarity", [](const MapArc& arc) -> py::object {
            return arc.similarity ? py::object(py::float_(*arc.similarity)) : py::none();
          },
          "Appearance similarity S_ij of the two key-images (Booij 2007 §B.2): epipolar-consistent matches over the\n"
          "fewer features of the two, in [0, 1]; None for maps written before it was stored (schema < 3).")
      .def_property_readonly(
          "feature_ids",
          [](const MapArc& arc) {
            py::array_t<int64_t> ids(static_cast<py::ssize_t>(arc.points.size()));
            for (size_t i = 0; i < arc.points.size(); ++i) ids.mutable_data()[i] = arc.points[i].feature_id;
            return ids;
          },
          "Ids of the features of M_k, int64 (N,).")
      .def_property_readonly(
          "points",
          [](const MapArc& arc) {
            py::array_t<double> points({static_cast<py::ssize_t>(arc.points.size()), py::ssize_t{3}});
            for (size_t i = 0; i < arc.points.size(); ++i) {
              std::memcpy(points.mutable_data() + 3 * i, arc.points[i].point_in_from.data(), 3 * sizeof(double));
            }
            return points;
          },
          "3D points (N, 3) of those features in node_from's camera frame, in the arc's unit of length.")
      .def_property_readonly(
          "rotation",
          [](const MapArc& arc) {
            py::array_t<double> r({3, 3});
            for (int i = 0; i < 3; ++i) {
              for (int j = 0; j < 3; ++j) r.mutable_at(i, j) = arc.to_from_from.rotation(i, j);
            }
            return r;
          },
          "R of x_to = R x_from + t (3, 3).")
      .def_property_readonly(
          "translation",
          [](const MapArc& arc) {
            py::array_t<double> t(3);
            for (int i = 0; i < 3; ++i) t.mutable_at(i) = arc.to_from_from.translation(i);
            return t;
          },
          "t of x_to = R x_from + t (3,), of unit length.")
      .def_property_readonly(
          "to_from_from", [](const MapArc& arc) { return MatrixFromRigid(arc.to_from_from); },
          "The motion as a 4x4 matrix [R t; 0 1] mapping node_from's camera frame to node_to's.")
      .def("__repr__", [](const MapArc& arc) {
        return fmt::format("<retrace.Arc {}: {} -> {}, {}, {} features, sigma_p {:.3f} px>", arc.id, arc.from, arc.to,
                           arc.kind, arc.points.size(), arc.sigma_p);
      });

  py::class_<NodeScale>(module, "Scale",
                        "Relative scale at a node between the geometries of the arc ending there (arc_in) and the\n"
                        "arc starting there (arc_out): a length in units of arc_out times `scale` is in units of "
                        "arc_in.")
      .def_readonly("node", &NodeScale::node, "The node where the two arcs meet.")
      .def_readonly("arc_in", &NodeScale::arc_in, "The arc ending at the node.")
      .def_readonly("arc_out", &NodeScale::arc_out, "The arc starting at the node.")
      .def_readonly("scale", &NodeScale::scale, "Length in units of arc_in per unit of arc_out.")
      .def("__repr__", [](const NodeScale& s) {
        return fmt::format("<retrace.Scale at node {}: arc {} -> arc {}, {:.4f}>", s.node, s.arc_in, s.arc_out,
                           s.scale);
      });

  py::class_<OpenedMap>(module, "Map",
                        "A map written by teach (`retrace teach` or retrace.Teacher), opened and read.\n\n"
                        "Map(path, load_images=True) checks the file as every command does (SQLite integrity, every\n"
                        "reference, the checksum of each key-image, finite geometry) and raises retrace.InputError\n"
                        "naming the file and the first fault. An incomplete map (its teach did not finish) opens,\n"
                        "with complete == False and a warning.")
      .def(py::init([](const py::object& path, bool load_images) {
             return OpenMap(PathFromObject(path, "path"), load_images);
           }),
           py::arg("path"), py::arg("load_images") = true,
           "Opens and reads the map file at `path`; key-images are decoded only with load_images=True.")
      .def_property_readonly(
          "path", [](const OpenedMap& m) { return m.path.string(); }, "The map file.")
      .def_property_readonly(
          "nodes",
          [](const py::object& self) { return ReferenceList(self.cast<const OpenedMap&>().map.nodes(), self); },
          "The nodes (key-images) in the order teach added them.")
      .def_property_readonly(
          "arcs", [](const py::object& self) { return ReferenceList(self.cast<const OpenedMap&>().map.arcs(), self); },
          "The arcs in the order teach added them.")
      .def_property_readonly(
          "scales",
          [](const py::object& self) { return ReferenceList(self.cast<const OpenedMap&>().map.scales(), self); },
          "The relative scales stored at nodes between consecutive arcs.")
      .def_property_readonly(
          "camera", [](const OpenedMap& m) { return m.camera; },
          "The camera of the key-images (retrace.Camera), or None when the map stores none.")
      .def_readonly("metadata", &OpenedMap::metadata,
                    "Key/value text teach stored: source_sequence, method, width, r_p, min_features, teach_state, "
                    "retrace version, ...")
      .def_readonly("complete", &OpenedMap::complete, "Whether the teach that wrote the map finished.")
      .def_readonly("image_bytes", &OpenedMap::image_bytes, "Bytes of the encoded key-images stored in the file.")
      .def(
          "node",
          [](const py::object& self, node_t id) {
            const MapNode* node = self.cast<const OpenedMap&>().map.FindNode(id);
            if (!node) throw py::key_error(fmt::format("the map has no node {}", id));
            return py::cast(node, py::return_value_policy::reference_internal, self);
          },
          py::arg("id"), "The node with this id (KeyError when there is none).")
      .def(
          "arc",
          [](const py::object& self, arc_t id) {
            const MapArc* arc = self.cast<const OpenedMap&>().map.FindArc(id);
            if (!arc) throw py::key_error(fmt::format("the map has no arc {}", id));
            return py::cast(arc, py::return_value_policy::reference_internal, self);
          },
          py::arg("id"), "The arc with this id (KeyError when there is none).")
      .def(
          "arcs_from",
          [](const py::object& self, node_t node) {
            return ReferenceList(self.cast<const OpenedMap&>().map.ArcsFrom(node), self);
          },
          py::arg("node"), "The arcs leaving a node.")
      .def(
          "arcs_to",
          [](const py::object& self, node_t node) {
            return ReferenceList(self.cast<const OpenedMap&>().map.ArcsTo(node), self);
          },
          py::arg("node"), "The arcs entering a node.")
      .def("__repr__", [](const OpenedMap& m) {
        return fmt::format("<retrace.Map {}: {} nodes, {} arcs{}>", m.path.string(), m.map.nodes().size(),
                           m.map.arcs().size(), m.complete ? "" : ", INCOMPLETE");
      });
}

}  // namespace retrace::python
