#include "retrace/camera/camera_io.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <regex>
#include <sstream>
#include <vector>

#include <fmt/format.h>
#include <opencv2/core/types.hpp>
#include <yaml-cpp/yaml.h>

#include "retrace/camera/camera_checks.h"
#include "retrace/camera/equirectangular_camera.h"
#include "retrace/camera/perspective_camera.h"
#include "retrace/camera/unified_camera.h"
#include "retrace/util/error.h"

namespace retrace {
namespace {

constexpr std::uintmax_t kMaxFileBytes = 16 << 20;  // calibration files are tiny; refuse anything huge

// A matrix read from a file: {rows, cols, data} maps, flat or nested sequences.
struct Matrix {
  int rows = 0;
  int cols = 0;
  std::vector<double> data;  // row-major
};

// Reads one calibration file's YAML tree and turns problems into InputError naming the file.
class Reader {
 public:
  explicit Reader(std::string source) : source_(std::move(source)) {}

  // Throws the InputError; the message stays on one line even when it quotes text from the file.
  [[noreturn]] void Fail(std::string problem) const {
    std::replace_if(problem.begin(), problem.end(), [](char c) { return c == '\n' || c == '\r'; }, ' ');
    throw InputError(source_, problem);
  }

  static std::string Trim(const std::string& s) {
    const auto begin = s.find_first_not_of(" \t\r\n");
    if (begin == std::string::npos) return "";
    return s.substr(begin, s.find_last_not_of(" \t\r\n") - begin + 1);
  }

  // First of `keys` present in the map `node`, or an undefined node.
  static YAML::Node Find(const YAML::Node& node, std::initializer_list<const char*> keys, std::string* found = nullptr) {
    for (const char* key : keys) {
      if (node[key]) {
        if (found) *found = key;
        return node[key];
      }
    }
    return YAML::Node(YAML::NodeType::Undefined);
  }

  YAML::Node Require(const YAML::Node& node, std::initializer_list<const char*> keys, std::string* found = nullptr) const {
    YAML::Node value = Find(node, keys, found);
    if (!value) {
      std::string names;
      for (const char* key : keys) names += std::string(names.empty() ? "'" : " or '") + key + "'";
      Fail("missing key " + names);
    }
    return value;
  }

  double Number(const YAML::Node& node, const std::string& what) const {
    if (!node.IsScalar()) Fail(what + " must be a number");
    const std::string text = Trim(node.Scalar());
    const char* begin = text.c_str();
    char* end = nullptr;
    const double value = std::strtod(begin, &end);
    if (text.empty() || end != begin + text.size()) Fail(what + " must be a number, not '" + text.substr(0, 40) + "'");
    if (!std::isfinite(value)) Fail(what + " is not finite");
    return value;
  }

  int Integer(const YAML::Node& node, const std::string& what) const {
    const double value = Number(node, what);
    if (value != std::floor(value) || std::abs(value) > 1e9) Fail(what + " must be an integer");
    return static_cast<int>(value);
  }

  std::string String(const YAML::Node& node, const std::string& what) const {
    if (!node.IsScalar()) Fail(what + " must be a string");
    return Trim(node.Scalar());
  }

  void Flatten(const YAML::Node& node, const std::string& what, std::vector<double>* out) const {
    if (node.IsSequence()) {
      for (const YAML::Node& element : node) Flatten(element, what, out);
    } else {
      out->push_back(Number(node, "an element of " + what));
    }
  }

  // A {rows, cols, data} map (ROS, OpenCV !!opencv-matrix, EuRoC T_BS) or a plain sequence of numbers.
  Matrix ReadMatrix(const YAML::Node& node, const std::string& what) const {
    Matrix m;
    if (node.IsMap()) {
      const YAML::Node data = node["data"];
      if (!data) Fail("missing key 'data' in " + what);
      if (!data.IsSequence()) Fail(what + ".data must be a list of numbers");
      Flatten(data, what, &m.data);
      m.rows = node["rows"] ? Integer(node["rows"], what + ".rows") : 1;
      m.cols = node["cols"] ? Integer(node["cols"], what + ".cols") : static_cast<int>(m.data.size());
      if (m.rows < 0 || m.cols < 0 || static_cast<size_t>(m.rows) * m.cols != m.data.size()) {
        Fail(fmt::format("{} says {}x{} but has {} values", what, m.rows, m.cols, m.data.size()));
      }
    } else if (node.IsSequence()) {
      Flatten(node, what, &m.data);
      m.rows = 1;
      m.cols = static_cast<int>(m.data.size());
    } else {
      Fail(what + " must be a matrix (rows, cols, data) or a list of numbers");
    }
    return m;
  }

  // The 3x3 calibration matrix; checks its shape, last row and focal lengths.
  Matrix3d ReadK(const YAML::Node& node, const std::string& what) const {
    const Matrix m = ReadMatrix(node, what);
    if (m.data.size() != 9 || (m.rows != 3 && m.rows != 1)) {
      Fail(fmt::format("wrong matrix size: {} is {}x{}, expected 3x3", what, m.rows, m.cols));
    }
    Matrix3d k;
    for (int i = 0; i < 9; ++i) k(i / 3, i % 3) = m.data[i];
    CheckK(k, what);
    return k;
  }

  void CheckK(const Matrix3d& k, const std::string& what) const {
    if (k(1, 0) != 0.0 || k(2, 0) != 0.0 || k(2, 1) != 0.0 || std::abs(k(2, 2) - 1.0) > 1e-9) {
      Fail(what + " is not a calibration matrix [fx s cx; 0 fy cy; 0 0 1]");
    }
    CheckFocal(k(0, 0), k(1, 1));
  }

  void CheckFocal(double fx, double fy) const {
    if (!(fx > 0.0) || !(fy > 0.0)) Fail(fmt::format("non-positive focal length (fx={}, fy={})", fx, fy));
  }

  // Distortion from a coefficient list in OpenCV order k1 k2 p1 p2 [k3 [k4 k5 k6 [s1..s4 [tx ty]]]].
  LensDistortion ReadDistortion(const YAML::Node& coefficients_node, const std::string& what,
                                const std::string& model) const {
    static const char* kRadialTangential[] = {"plumb_bob", "radtan", "radial-tangential", "radial_tangential",
                                              "rational_polynomial", "pinhole", ""};
    if (std::find(std::begin(kRadialTangential), std::end(kRadialTangential), model) ==
        std::end(kRadialTangential)) {
      Fail("unknown distortion model '" + model + "' (supported: plumb_bob / radial-tangential)");
    }
    LensDistortion d;
    if (!coefficients_node) return d;
    const Matrix m = ReadMatrix(coefficients_node, what);
    const std::vector<double>& c = m.data;
    const size_t n = c.size();
    if (n != 0 && n != 4 && n != 5 && n != 8 && n != 12 && n != 14) {
      Fail(fmt::format("{} has {} values, expected 4, 5, 8, 12 or 14 (k1 k2 p1 p2 [k3 ...])", what, n));
    }
    if (n == 0) return d;
    d.k1 = c[0];
    d.k2 = c[1];
    d.p1 = c[2];
    d.p2 = c[3];
    if (n >= 5) d.k3 = c[4];
    for (size_t i = 5; i < n; ++i) {
      if (c[i] != 0.0) Fail(what + " has non-zero rational/thin-prism terms (k4..), which retrace does not support");
    }
    return d;
  }

  // Combines the image size stated in the file (if any) with the one of the images (if given).
  cv::Size ResolveSize(std::optional<cv::Size> in_file, std::optional<cv::Size> given) const {
    if (in_file && (in_file->width <= 0 || in_file->height <= 0)) {
      Fail(fmt::format("invalid image size {}x{} in file", in_file->width, in_file->height));
    }
    if (given && (given->width <= 0 || given->height <= 0)) {
      Fail(fmt::format("invalid image size {}x{}", given->width, given->height));
    }
    if (in_file && given && *in_file != *given) {
      Fail(fmt::format("image size mismatch: file says {}x{}, images are {}x{}", in_file->width, in_file->height,
                       given->width, given->height));
    }
    if (in_file) return *in_file;
    if (given) return *given;
    Fail("the file has no image size and none was given (pass the image size, e.g. --image-size WxH)");
  }

  std::optional<cv::Size> ReadSize(const YAML::Node& root) const {
    if (root["image_width"] || root["image_height"]) {
      return cv::Size(Integer(Require(root, {"image_width"}), "image_width"),
                      Integer(Require(root, {"image_height"}), "image_height"));
    }
    std::string key;
    if (YAML::Node size = Find(root, {"imageSize", "image_size", "resolution"}, &key)) {
      const Matrix m = ReadMatrix(size, key);
      if (m.data.size() != 2) Fail(key + " must have two values [width, height]");
      if (m.data[0] != std::floor(m.data[0]) || m.data[1] != std::floor(m.data[1])) Fail(key + " must be integers");
      return cv::Size(static_cast<int>(m.data[0]), static_cast<int>(m.data[1]));
    }
    if (root["width"] || root["height"]) {
      return cv::Size(Integer(Require(root, {"width"}), "width"), Integer(Require(root, {"height"}), "height"));
    }
    return std::nullopt;
  }

  // ROS camera_info, OpenCV FileStorage and retrace files: all have a 3x3 camera matrix.
  std::unique_ptr<CameraModel> ReadMatrixFile(const YAML::Node& root, std::optional<cv::Size> image_size) const {
    std::string model = "perspective";
    if (root["camera_model"]) model = String(root["camera_model"], "camera_model");
    if (model == "pinhole") model = "perspective";
    if (model != "perspective" && model != "unified" && model != "equirectangular") {
      Fail("unknown camera_model '" + model + "' (expected perspective, unified or equirectangular)");
    }
    if (model == "perspective" && root["xi"]) model = "unified";  // OpenCV omnidir calibration output
    const cv::Size size = ResolveSize(ReadSize(root), image_size);
    if (model == "equirectangular") return std::make_unique<EquirectangularCamera>(size.width, size.height);

    std::string k_key;
    const YAML::Node k_node = Require(root, {"camera_matrix", "cameraMatrix", "K", "M1"}, &k_key);
    const Matrix3d k = ReadK(k_node, k_key);
    std::string d_key;
    const YAML::Node d_node =
        k_key == "M1" ? Find(root, {"D1"}, &d_key)
                      : Find(root, {"distortion_coefficients", "distortion_coeffs", "dist_coeffs", "distCoeffs",
                                    "distortion", "D"},
                             &d_key);
    std::string distortion_model;
    if (root["distortion_model"]) distortion_model = String(root["distortion_model"], "distortion_model");
    const LensDistortion distortion = ReadDistortion(d_node, d_key, distortion_model);
    if (model == "unified") {
      const YAML::Node xi_node = Require(root, {"xi"});
      double xi = 0.0;
      if (xi_node.IsScalar()) {
        xi = Number(xi_node, "xi");
      } else {
        const Matrix m = ReadMatrix(xi_node, "xi");  // OpenCV omnidir writes xi as a 1x1 matrix
        if (m.data.size() != 1) Fail("xi must be one number");
        xi = m.data[0];
      }
      if (xi < 0.0) Fail(fmt::format("xi must be non-negative, not {}", xi));
      return std::make_unique<UnifiedCamera>(size.width, size.height, xi, k(0, 0), k(1, 1), k(0, 2), k(1, 2),
                                             k(0, 1), distortion);
    }
    return std::make_unique<PerspectiveCamera>(size.width, size.height, k(0, 0), k(1, 1), k(0, 2), k(1, 2), k(0, 1),
                                               distortion);
  }

  // EuRoC / Kalibr sensor.yaml: resolution [w, h], intrinsics [fu fv cu cv] (omni: [xi fu fv cu cv]).
  std::unique_ptr<CameraModel> ReadEurocFile(const YAML::Node& root, std::optional<cv::Size> image_size) const {
    std::string model = "pinhole";
    if (root["camera_model"]) model = String(root["camera_model"], "camera_model");
    if (model != "pinhole" && model != "omni") {
      Fail("unknown camera_model '" + model + "' (supported in sensor.yaml: pinhole, omni)");
    }
    const cv::Size size = ResolveSize(ReadSize(root), image_size);
    const Matrix intrinsics = ReadMatrix(root["intrinsics"], "intrinsics");
    const size_t expected = model == "omni" ? 5 : 4;
    if (intrinsics.data.size() != expected) {
      Fail(fmt::format("wrong matrix size: intrinsics has {} values, expected {} for camera_model {}",
                       intrinsics.data.size(), expected, model));
    }
    const size_t o = expected - 4;  // offset past xi
    const double fx = intrinsics.data[o], fy = intrinsics.data[o + 1];
    CheckFocal(fx, fy);
    std::string distortion_model = "radial-tangential";
    if (root["distortion_model"]) distortion_model = String(root["distortion_model"], "distortion_model");
    std::string d_key = "distortion_coefficients";
    const YAML::Node d_node = Find(root, {"distortion_coefficients", "distortion_coeffs"}, &d_key);
    const LensDistortion distortion = ReadDistortion(d_node, d_key, distortion_model);
    if (model == "omni") {
      return std::make_unique<UnifiedCamera>(size.width, size.height, intrinsics.data[0], fx, fy,
                                             intrinsics.data[o + 2], intrinsics.data[o + 3], 0.0, distortion);
    }
    return std::make_unique<PerspectiveCamera>(size.width, size.height, fx, fy, intrinsics.data[2],
                                               intrinsics.data[3], 0.0, distortion);
  }

  // KITTI calib.txt: "P0: p00 p01 ... p23" (3x4, row-major), one line per camera: P0 and P1 the grey pair, P2 and P3
  // the colour pair (image_0 .. image_3). `key` names the one to read.
  std::unique_ptr<CameraModel> ReadKittiFile(const std::string& text, std::optional<cv::Size> image_size,
                                             const std::string& key) const {
    std::istringstream lines(text);
    std::string line;
    while (std::getline(lines, line)) {
      line = Trim(line);
      if (line.rfind(key + ":", 0) != 0) continue;
      std::istringstream values(line.substr(key.size() + 1));
      std::vector<double> p;
      std::string token;
      while (values >> token) {
        char* end = nullptr;
        const double value = std::strtod(token.c_str(), &end);
        if (end != token.c_str() + token.size() || !std::isfinite(value)) {
          Fail(key + " has a non-numeric value '" + token.substr(0, 40) + "'");
        }
        p.push_back(value);
      }
      if (p.size() != 12) Fail(fmt::format("wrong matrix size: {} has {} values, expected 12 (3x4)", key, p.size()));
      Matrix3d k;
      k << p[0], p[1], p[2], p[4], p[5], p[6], p[8], p[9], p[10];
      CheckK(k, key);
      const cv::Size size = ResolveSize(std::nullopt, image_size);
      return std::make_unique<PerspectiveCamera>(size.width, size.height, k(0, 0), k(1, 1), k(0, 2), k(1, 2),
                                                 k(0, 1), LensDistortion());
    }
    Fail("missing key '" + key + "'");
  }

  // OpenCV FileStorage XML, parsed here into the same YAML tree the YAML files give. (OpenCV 4.6's own XML parser
  // crashes on some truncated files, e.g. one ending inside an attribute, so it is not used for untrusted input.)
  // The format: <opencv_storage> holds elements; an element holds child elements (a map, or a sequence when all
  // children are named "_") or text: one token is a scalar, several (or type_id="opencv-matrix" data) a sequence.
  YAML::Node ParseXml(const std::string& text) const {
    size_t at = 0;
    const auto skip_space = [&]() {
      while (at < text.size() && std::isspace(static_cast<unsigned char>(text[at]))) ++at;
    };
    // Skips the prolog, comments and declarations (<?...?>, <!--...-->, <!...>).
    const auto skip_markup = [&]() {
      for (;;) {
        skip_space();
        if (text.compare(at, 4, "<!--") == 0) {
          const size_t end = text.find("-->", at + 4);
          if (end == std::string::npos) Fail("not valid XML: unterminated comment");
          at = end + 3;
        } else if (text.compare(at, 2, "<?") == 0 || text.compare(at, 2, "<!") == 0) {
          const size_t end = text.find('>', at + 2);
          if (end == std::string::npos) Fail("not valid XML: unterminated declaration");
          at = end + 1;
        } else {
          return;
        }
      }
    };
    std::function<YAML::Node(int, std::string*)> parse_element = [&](int depth, std::string* name) -> YAML::Node {
      if (depth > 32) Fail("XML nested too deeply for a calibration file");
      skip_markup();
      if (at >= text.size() || text[at] != '<') Fail("not valid XML: expected an element");
      const size_t tag_end = text.find('>', at);
      if (tag_end == std::string::npos) Fail("not valid XML: unterminated tag");
      std::string tag = text.substr(at + 1, tag_end - at - 1);
      at = tag_end + 1;
      const bool empty = !tag.empty() && tag.back() == '/';
      if (empty) tag.pop_back();
      const size_t name_end = tag.find_first_of(" \t\r\n");
      *name = tag.substr(0, name_end);
      if (name->empty() || !std::all_of(name->begin(), name->end(), [](char ch) {
            return std::isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '-' || ch == '.' || ch == ':';
          })) {
        Fail("not valid XML: bad element name '" + name->substr(0, 40) + "'");
      }
      const bool is_matrix = tag.find("opencv-matrix") != std::string::npos;
      if (empty) return YAML::Node(YAML::NodeType::Null);
      const std::string closing = "</" + *name + ">";
      skip_markup();
      if (text.compare(at, 1, "<") == 0 && text.compare(at, 2, "</") != 0) {
        // Child elements.
        std::vector<std::pair<std::string, YAML::Node>> children;
        for (;;) {
          skip_markup();
          if (text.compare(at, 2, "</") == 0) break;
          std::string child_name;
          YAML::Node child = parse_element(depth + 1, &child_name);
          children.emplace_back(child_name, child);
        }
        if (text.compare(at, closing.size(), closing) != 0) Fail("not valid XML: missing " + closing);
        at += closing.size();
        const bool is_sequence = std::all_of(children.begin(), children.end(), [](const auto& c) {
          return c.first == "_";
        });
        YAML::Node node(is_sequence ? YAML::NodeType::Sequence : YAML::NodeType::Map);
        for (const auto& [child_name, child] : children) {
          if (is_sequence) {
            node.push_back(child);
          } else {
            node[child_name] = child;
          }
        }
        if (is_matrix && node.IsMap() && node["data"] && node["data"].IsScalar()) {
          YAML::Node data(YAML::NodeType::Sequence);
          data.push_back(node["data"]);
          node["data"] = data;
        }
        return node;
      }
      // Text content.
      const size_t end = text.find(closing, at);
      const size_t next_tag = text.find('<', at);
      if (end == std::string::npos || next_tag != end) Fail("not valid XML: missing " + closing);
      std::string content = Trim(text.substr(at, end - at));
      at = end + closing.size();
      if (content.size() >= 2 && content.front() == '"' && content.back() == '"') {
        return YAML::Node(content.substr(1, content.size() - 2));
      }
      std::istringstream tokens(content);
      std::vector<std::string> values;
      for (std::string token; tokens >> token;) values.push_back(token);
      if (values.size() == 1 && *name != "data") return YAML::Node(values[0]);
      YAML::Node sequence(YAML::NodeType::Sequence);
      for (const std::string& value : values) sequence.push_back(value);
      return sequence;
    };
    std::string root_name;
    YAML::Node root = parse_element(0, &root_name);
    if (root_name != "opencv_storage") Fail("not an OpenCV XML file: the root element is <" + root_name + ">");
    return root;
  }

  YAML::Node ParseYaml(std::string text) const {
    // OpenCV writes the directive as "%YAML:1.0", which is not YAML 1.2; drop it.
    if (text.rfind("%YAML:", 0) == 0) text = "#" + text;
    try {
      return YAML::Load(text);
    } catch (const YAML::Exception& e) {
      Fail(fmt::format("not valid YAML (line {}: {})", e.mark.line + 1, e.msg));
    }
  }

 private:
  std::string source_;
};

std::string ReadText(const Reader& reader, const std::filesystem::path& path) {
  std::error_code error;
  if (!std::filesystem::exists(path, error)) reader.Fail("file not found");
  if (std::filesystem::is_directory(path, error)) reader.Fail("is a directory, not a calibration file");
  const std::uintmax_t bytes = std::filesystem::file_size(path, error);
  if (error) reader.Fail("cannot read file (" + error.message() + ")");
  if (bytes > kMaxFileBytes) reader.Fail(fmt::format("{} bytes is far too large for a calibration file", bytes));
  std::ifstream stream(path, std::ios::binary);
  if (!stream) reader.Fail("cannot open file");
  std::ostringstream buffer;
  buffer << stream.rdbuf();
  std::string text = buffer.str();
  if (Reader::Trim(text).empty()) reader.Fail("empty file");
  if (text.find('\0') != std::string::npos) reader.Fail("binary data, not a calibration file");
  return text;
}

}  // namespace

std::unique_ptr<CameraModel> ReadCameraFile(const std::filesystem::path& path, std::optional<cv::Size> image_size,
                                             const std::string& camera) {
  const Reader reader(path.string());
  return ParseCameraText(ReadText(reader, path), path.string(), image_size, camera);
}

namespace {

std::unique_ptr<CameraModel> ParseCameraFormats(const std::string& text, const std::string& source,
                                                std::optional<cv::Size> image_size, const std::string& camera) {
  const Reader reader(source);
  if (Reader::Trim(text).empty()) reader.Fail("empty camera text");
  if (text.find('\0') != std::string::npos) reader.Fail("binary data, not a calibration file");
  if (!camera.empty() && !std::regex_match(camera, std::regex("P[0-3]"))) {
    reader.Fail("no camera '" + camera.substr(0, 40) + "' in a calibration file (KITTI's are P0 to P3)");
  }
  // A KITTI calib.txt has all four cameras' lines, P0 first (an OpenCV stereo file may have keys P1 and P2).
  if (std::regex_search(text, std::regex(R"((^|\n)\s*P0\s*:)"))) {
    return reader.ReadKittiFile(text, image_size, camera.empty() ? "P0" : camera);
  }

  const bool is_xml = Reader::Trim(text).rfind("<?xml", 0) == 0 || Reader::Trim(text).rfind("<opencv_storage", 0) == 0;
  const YAML::Node root = is_xml ? reader.ParseXml(text) : reader.ParseYaml(text);
  if (!root.IsMap()) {
    reader.Fail(std::string("not a camera calibration file: expected a YAML mapping of keys, found a ") +
                (root.IsSequence() ? "list" : root.IsScalar() ? "plain text" : "empty document"));
  }
  try {
    if (root["intrinsics"]) return reader.ReadEurocFile(root, image_size);
    // Kalibr camchain.yaml: the first camera, cam0, has the sensor.yaml keys.
    if (root["cam0"] && root["cam0"].IsMap() && root["cam0"]["intrinsics"]) {
      return reader.ReadEurocFile(root["cam0"], image_size);
    }
    if (root["camera_matrix"] || root["cameraMatrix"] || root["K"] || root["M1"] || root["camera_model"]) {
      return reader.ReadMatrixFile(root, image_size);
    }
  } catch (const YAML::Exception& e) {
    reader.Fail(fmt::format("unexpected YAML structure ({})", e.msg));
  }
  reader.Fail("not a camera calibration file: missing key 'camera_matrix' (or cameraMatrix, K, intrinsics, P0)");
}

}  // namespace

// Every reader ends here, so a calibration from a file, a ROS message or a map passes the same plausibility checks.
std::unique_ptr<CameraModel> ParseCameraText(const std::string& text, const std::string& source,
                                             std::optional<cv::Size> image_size, const std::string& camera_key) {
  std::unique_ptr<CameraModel> camera = ParseCameraFormats(text, source, image_size, camera_key);
  std::string problem;
  if (!CheckCameraPlausible(*camera, &problem)) throw InputError(source, "implausible calibration: " + problem);
  return camera;
}

namespace {

std::string FormatMatrix(const std::string& name, int rows, int cols, const std::vector<double>& data) {
  std::string values;
  for (size_t i = 0; i < data.size(); ++i) values += (i ? ", " : "") + fmt::format("{}", data[i]);
  return fmt::format("{}:\n  rows: {}\n  cols: {}\n  data: [{}]\n", name, rows, cols, values);
}

std::vector<double> DistortionValues(const LensDistortion& d, bool with_k3) {
  std::vector<double> values = {d.k1, d.k2, d.p1, d.p2};
  if (with_k3) values.push_back(d.k3);
  return values;
}

std::string CameraMatrixYaml(const Matrix3d& k) {
  return FormatMatrix("camera_matrix", 3, 3,
                      {k(0, 0), k(0, 1), k(0, 2), k(1, 0), k(1, 1), k(1, 2), k(2, 0), k(2, 1), k(2, 2)});
}

}  // namespace

std::string CameraToYaml(const CameraModel& camera) {
  std::string yaml = fmt::format("# Camera calibration written by retrace.\nimage_width: {}\nimage_height: {}\n",
                                 camera.width(), camera.height());
  if (const auto* perspective = dynamic_cast<const PerspectiveCamera*>(&camera)) {
    // ROS camera_info (camera_calibration_parsers) layout.
    const Matrix3d k = perspective->K();
    yaml += "camera_name: camera\n";
    yaml += CameraMatrixYaml(k);
    yaml += "distortion_model: plumb_bob\n";
    yaml += FormatMatrix("distortion_coefficients", 1, 5, DistortionValues(perspective->distortion(), true));
    yaml += FormatMatrix("rectification_matrix", 3, 3, {1, 0, 0, 0, 1, 0, 0, 0, 1});
    yaml += FormatMatrix("projection_matrix", 3, 4,
                         {k(0, 0), k(0, 1), k(0, 2), 0, 0, k(1, 1), k(1, 2), 0, 0, 0, 1, 0});
  } else if (const auto* unified = dynamic_cast<const UnifiedCamera*>(&camera)) {
    yaml += "camera_name: camera\ncamera_model: unified\n";
    yaml += fmt::format("xi: {}\n", unified->xi());
    yaml += CameraMatrixYaml(unified->K());
    yaml += "distortion_model: plumb_bob\n";
    const bool with_k3 = unified->distortion().k3 != 0.0;
    yaml += FormatMatrix("distortion_coefficients", 1, with_k3 ? 5 : 4, DistortionValues(unified->distortion(), with_k3));
  } else if (camera.type() == CameraModelType::kEquirectangular) {
    yaml += "camera_model: equirectangular\n";
  } else {
    throw std::invalid_argument("CameraToYaml: unknown camera model '" + camera.model_name() + "'");
  }
  return yaml;
}

void WriteCameraFile(const CameraModel& camera, const std::filesystem::path& path) {
  const std::string yaml = CameraToYaml(camera);
  std::ofstream stream(path);
  stream << yaml;
  stream.close();
  if (!stream) throw InputError(path.string(), "cannot write file");
}

std::string DescribeCamera(const CameraModel& camera) {
  std::string text = fmt::format("model: {}\nimage size: {}x{}\n", camera.model_name(), camera.width(),
                                 camera.height());
  const auto describe_distortion = [](const LensDistortion& d) {
    return fmt::format("distortion: k1={:.6g} k2={:.6g} k3={:.6g} p1={:.6g} p2={:.6g}\n", d.k1, d.k2, d.k3, d.p1,
                       d.p2);
  };
  if (const auto* p = dynamic_cast<const PerspectiveCamera*>(&camera)) {
    text += fmt::format("fx={:.4f} fy={:.4f} cx={:.4f} cy={:.4f} skew={:.4g}\n", p->fx(), p->fy(), p->cx(), p->cy(),
                        p->skew());
    text += describe_distortion(p->distortion());
  } else if (const auto* u = dynamic_cast<const UnifiedCamera*>(&camera)) {
    text += fmt::format("xi={:.6f} fx={:.4f} fy={:.4f} cx={:.4f} cy={:.4f} skew={:.4g}\n", u->xi(), u->fx(), u->fy(),
                        u->cx(), u->cy(), u->skew());
    text += describe_distortion(u->distortion());
  }
  text += fmt::format("focal length: {:.4f} px per radian at the centre\n", camera.FocalLength());
  return text;
}

}  // namespace retrace
