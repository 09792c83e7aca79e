#include "retrace/camera/camera_io.h"

#include <fstream>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "retrace/camera/equirectangular_camera.h"
#include "retrace/camera/perspective_camera.h"
#include "retrace/camera/unified_camera.h"
#include "retrace/util/error.h"
#include "retrace/util/testing.h"

namespace retrace {
namespace {

class CameraIoTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = testing::MakeTempDir("camera_io_test"); }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::filesystem::path Write(const std::string& name, const std::string& content) {
    const std::filesystem::path path = dir_ / name;
    std::ofstream(path, std::ios::binary) << content;
    return path;
  }

  // Reading `path` must throw InputError with a one-line message naming the file and containing `problem`.
  void ExpectInputError(const std::filesystem::path& path, const std::string& problem,
                        std::optional<cv::Size> size = std::nullopt) {
    try {
      ReadCameraFile(path, size);
      ADD_FAILURE() << path << " was accepted, expected: " << problem;
    } catch (const InputError& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find(path.string()), std::string::npos) << message;
      EXPECT_NE(message.find(problem), std::string::npos) << message << "\n  expected to contain: " << problem;
      EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    }
  }

  std::filesystem::path dir_;
};

const PerspectiveCamera& AsPerspective(const std::unique_ptr<CameraModel>& camera) {
  EXPECT_EQ(camera->type(), CameraModelType::kPerspective);
  return dynamic_cast<const PerspectiveCamera&>(*camera);
}

TEST_F(CameraIoTest, ReadsKittiCalibWithGivenImageSize) {
  RETRACE_REQUIRE_SHARED_DATA(calib, "kitti07/calib.txt");
  const auto camera = ReadCameraFile(calib, cv::Size(1226, 370));
  const PerspectiveCamera& p = AsPerspective(camera);
  EXPECT_EQ(p.width(), 1226);
  EXPECT_EQ(p.height(), 370);
  EXPECT_DOUBLE_EQ(p.fx(), 707.0912);
  EXPECT_DOUBLE_EQ(p.fy(), 707.0912);
  EXPECT_DOUBLE_EQ(p.cx(), 601.8873);
  EXPECT_DOUBLE_EQ(p.cy(), 183.1104);
  EXPECT_TRUE(p.distortion().IsZero());
  ExpectInputError(calib, "has no image size");
}

// A calib.txt holds the four cameras of a KITTI sequence: each is read by its name, P0 by default; a name that is
// not KITTI's, or a camera the file lacks, is a one-line error.
TEST_F(CameraIoTest, ReadsTheKittiCameraNamed) {
  const auto path = Write("calib.txt",
                          "P0: 700 0 600 0 0 701 180 0 0 0 1 0\n"
                          "P1: 710 0 610 -380 0 711 181 0 0 0 1 0\n"
                          "P2: 720 0 620 46 0 721 182 0.2 0 0 1 0.003\n");
  const cv::Size size(1241, 376);
  EXPECT_DOUBLE_EQ(AsPerspective(ReadCameraFile(path, size)).fx(), 700.0);
  EXPECT_DOUBLE_EQ(AsPerspective(ReadCameraFile(path, size, "P0")).fx(), 700.0);
  const std::unique_ptr<CameraModel> camera_2 = ReadCameraFile(path, size, "P2");
  const PerspectiveCamera& p2 = AsPerspective(camera_2);
  EXPECT_DOUBLE_EQ(p2.fx(), 720.0);
  EXPECT_DOUBLE_EQ(p2.fy(), 721.0);
  EXPECT_DOUBLE_EQ(p2.cx(), 620.0);
  EXPECT_DOUBLE_EQ(p2.cy(), 182.0);
  EXPECT_DOUBLE_EQ(AsPerspective(ReadCameraFile(path, size, "P1")).cx(), 610.0);
  for (const auto& [camera, problem] : std::vector<std::pair<std::string, std::string>>{
           {"P3", "missing key 'P3'"}, {"P7", "no camera 'P7'"}, {"cam1", "no camera 'cam1'"}}) {
    try {
      ReadCameraFile(path, size, camera);
      ADD_FAILURE() << camera << " was accepted";
    } catch (const InputError& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find(path.string()), std::string::npos) << message;
      EXPECT_NE(message.find(problem), std::string::npos) << message;
    }
  }
  // An OpenCV stereo file, whose rectified projections are keys P1 and P2, is not taken for KITTI's.
  const auto stereo = Write("stereo.yml",
                            "%YAML:1.0\nM1: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n"
                            "  data: [ 300., 0., 160., 0., 300., 120., 0., 0., 1. ]\n"
                            "P1: !!opencv-matrix\n  rows: 3\n  cols: 4\n  dt: d\n"
                            "  data: [ 310., 0., 150., 0., 0., 310., 110., 0., 0., 0., 1., 0. ]\n");
  EXPECT_DOUBLE_EQ(AsPerspective(ReadCameraFile(stereo, cv::Size(320, 240))).fx(), 300.0);
  // A file of one camera (not KITTI's) ignores the name.
  const auto yaml = Write("camera.yaml", CameraToYaml(PerspectiveCamera(64, 48, 50, 50, 32, 24)));
  EXPECT_DOUBLE_EQ(AsPerspective(ReadCameraFile(yaml, std::nullopt, "P2")).fx(), 50.0);
}

TEST_F(CameraIoTest, ReadsEurocSensorYaml) {
  RETRACE_REQUIRE_SHARED_DATA(sensor, "euroc_v101_clip/mav0/cam0/sensor.yaml");
  const auto camera = ReadCameraFile(sensor);
  const PerspectiveCamera& p = AsPerspective(camera);
  EXPECT_EQ(p.width(), 752);
  EXPECT_EQ(p.height(), 480);
  EXPECT_DOUBLE_EQ(p.fx(), 458.654);
  EXPECT_DOUBLE_EQ(p.fy(), 457.296);
  EXPECT_DOUBLE_EQ(p.cx(), 367.215);
  EXPECT_DOUBLE_EQ(p.cy(), 248.375);
  EXPECT_DOUBLE_EQ(p.distortion().k1, -0.28340811);
  EXPECT_DOUBLE_EQ(p.distortion().k2, 0.07395907);
  EXPECT_DOUBLE_EQ(p.distortion().p1, 0.00019359);
  EXPECT_DOUBLE_EQ(p.distortion().p2, 1.76187114e-05);
  EXPECT_EQ(p.distortion().k3, 0.0);
  EXPECT_EQ(ReadCameraFile(sensor, cv::Size(752, 480))->width(), 752);
  ExpectInputError(sensor, "image size mismatch: file says 752x480, images are 640x480", cv::Size(640, 480));
}

TEST_F(CameraIoTest, ReadsOpenCvCalibrationYaml) {
  RETRACE_REQUIRE_SHARED_DATA(file, "chessboard_640x480/left_intrinsics.yml");
  const auto camera = ReadCameraFile(file);
  const PerspectiveCamera& p = AsPerspective(camera);
  EXPECT_EQ(p.width(), 640);
  EXPECT_EQ(p.height(), 480);
  EXPECT_DOUBLE_EQ(p.fx(), 5.3591573396163199e+02);
  EXPECT_DOUBLE_EQ(p.fy(), 5.3591573396163199e+02);
  EXPECT_DOUBLE_EQ(p.cx(), 3.4228315473308373e+02);
  EXPECT_DOUBLE_EQ(p.cy(), 2.3557082909788173e+02);
  EXPECT_DOUBLE_EQ(p.distortion().k1, -2.6637260909660682e-01);
  EXPECT_DOUBLE_EQ(p.distortion().k2, -3.8588898922304653e-02);
  EXPECT_DOUBLE_EQ(p.distortion().p1, 1.7831947042852964e-03);
  EXPECT_DOUBLE_EQ(p.distortion().p2, -2.8122100441115472e-04);
  EXPECT_DOUBLE_EQ(p.distortion().k3, 2.3839153080878486e-01);
}

TEST_F(CameraIoTest, ReadsOpenCvStereoIntrinsicsFirstCamera) {
  RETRACE_REQUIRE_SHARED_DATA(file, "chessboard_640x480/intrinsics.yml");
  const auto camera = ReadCameraFile(file, cv::Size(640, 480));
  const PerspectiveCamera& p = AsPerspective(camera);
  EXPECT_DOUBLE_EQ(p.fx(), 5.3480326845051309e+02);
  EXPECT_DOUBLE_EQ(p.cx(), 3.3568643204394891e+02);
  EXPECT_DOUBLE_EQ(p.distortion().k1, 2.9589439552724328e-01);
  EXPECT_DOUBLE_EQ(p.distortion().k2, -1.0354662043042675e+00);
  ExpectInputError(file, "has no image size");
}

TEST_F(CameraIoTest, ReadsRosCameraInfoAndMessageDump) {
  const auto file = Write("ros.yaml", R"(image_width: 640
image_height: 480
camera_name: narrow_stereo
camera_matrix:
  rows: 3
  cols: 3
  data: [430.15, 0, 306.5, 0, 430.2, 250.3, 0, 0, 1]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.3, 0.09, 0.001, -0.002, 0]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
projection_matrix:
  rows: 3
  cols: 4
  data: [430.15, 0, 306.5, 0, 0, 430.2, 250.3, 0, 0, 0, 1, 0]
)");
  const auto camera_1 = ReadCameraFile(file);
  const PerspectiveCamera& p = AsPerspective(camera_1);
  EXPECT_EQ(p.fx(), 430.15);
  EXPECT_EQ(p.cy(), 250.3);
  EXPECT_EQ(p.distortion().p2, -0.002);
  const auto message = Write("msg.yaml", R"(height: 480
width: 640
distortion_model: "plumb_bob"
D: [-0.3, 0.09, 0.001, -0.002, 0.0]
K: [430.15, 0.0, 306.5, 0.0, 430.2, 250.3, 0.0, 0.0, 1.0]
)");
  const auto camera_2 = ReadCameraFile(message);
  const PerspectiveCamera& m = AsPerspective(camera_2);
  EXPECT_EQ(m.width(), 640);
  EXPECT_EQ(m.fy(), 430.2);
  EXPECT_EQ(m.distortion().k1, -0.3);
}

TEST_F(CameraIoTest, ReadsKalibrOmniCamchain) {
  const auto file = Write("camchain.yaml", R"(cam0:
  cam_overlaps: []
  camera_model: omni
  distortion_coeffs: [-0.05, 0.003, 0.0007, -0.0003]
  distortion_model: radtan
  intrinsics: [1.04, 303.5, 303.7, 643.8, 521.1]
  resolution: [1280, 1024]
  rostopic: /cam0/image_raw
)");
  const auto camera = ReadCameraFile(file);
  ASSERT_EQ(camera->type(), CameraModelType::kUnified);
  const auto& u = dynamic_cast<const UnifiedCamera&>(*camera);
  EXPECT_EQ(u.width(), 1280);
  EXPECT_EQ(u.xi(), 1.04);
  EXPECT_EQ(u.fx(), 303.5);
  EXPECT_EQ(u.fy(), 303.7);
  EXPECT_EQ(u.cx(), 643.8);
  EXPECT_EQ(u.cy(), 521.1);
  EXPECT_EQ(u.distortion().k1, -0.05);
  EXPECT_EQ(u.distortion().p2, -0.0003);
}

TEST_F(CameraIoTest, ReadsOpenCvXml) {
  const std::filesystem::path file = dir_ / "camera.xml";
  {
    cv::FileStorage storage(file.string(), cv::FileStorage::WRITE);
    storage << "image_width" << 800 << "image_height" << 600;
    storage << "camera_matrix" << cv::Mat(cv::Matx33d(610.5, 0, 401.25, 0, 612.0, 299.5, 0, 0, 1));
    storage << "distortion_coefficients" << cv::Mat(cv::Matx<double, 1, 5>(-0.2, 0.05, 0.0, 0.0, 0.01));
  }
  const auto camera_3 = ReadCameraFile(file);
  const PerspectiveCamera& p = AsPerspective(camera_3);
  EXPECT_EQ(p.width(), 800);
  EXPECT_EQ(p.fx(), 610.5);
  EXPECT_EQ(p.cx(), 401.25);
  EXPECT_EQ(p.distortion().k3, 0.01);
  std::string deep = "<?xml version=\"1.0\"?>\n<opencv_storage>";
  for (int i = 0; i < 100000; ++i) deep += "<a>";
  ExpectInputError(Write("deep.xml", deep), "XML nested too deeply");
  ExpectInputError(Write("broken.xml", "<?xml version=\"1.0\"?>\n<opencv_storage><a>1</b>"), "not valid XML");
  ExpectInputError(Write("truncated.xml", "<?xml version=\"1.0\"?>\n<opencv_storage>\n<image_width>640</image_width>\n"
                                          "<camera_matrix type_id="),
                   "not valid XML");  // crashes OpenCV 4.6's own FileStorage parser
  ExpectInputError(Write("other.xml", "<?xml version=\"1.0\"?>\n<html><body>hi</body></html>"),
                   "the root element is <html>");
}

TEST_F(CameraIoTest, WriteReadRoundTripOfEveryModel) {
  LensDistortion d;
  d.k1 = -0.26637260909660682;
  d.k2 = -0.038588898922304653;
  d.k3 = 0.23839153080878486;
  d.p1 = 0.0017831947042852964;
  d.p2 = -0.00028122100441115472;
  const PerspectiveCamera perspective(640, 480, 535.91573396163199, 536.1, 342.28315473308373, 235.57082909788173,
                                      0.25, d);
  WriteCameraFile(perspective, dir_ / "perspective.yaml");
  const auto camera_4 = ReadCameraFile(dir_ / "perspective.yaml");
  const PerspectiveCamera& p = AsPerspective(camera_4);
  EXPECT_EQ(p.width(), 640);
  EXPECT_EQ(p.height(), 480);
  EXPECT_EQ(p.fx(), perspective.fx());
  EXPECT_EQ(p.fy(), perspective.fy());
  EXPECT_EQ(p.cx(), perspective.cx());
  EXPECT_EQ(p.cy(), perspective.cy());
  EXPECT_EQ(p.skew(), perspective.skew());
  EXPECT_EQ(p.distortion().k1, d.k1);
  EXPECT_EQ(p.distortion().k2, d.k2);
  EXPECT_EQ(p.distortion().k3, d.k3);
  EXPECT_EQ(p.distortion().p1, d.p1);
  EXPECT_EQ(p.distortion().p2, d.p2);

  LensDistortion omni;
  omni.k1 = -0.1234567891234;
  omni.k2 = 0.0321;
  omni.p1 = 7.5e-4;
  omni.p2 = -3.1e-5;
  const UnifiedCamera unified(1280, 1024, 0.9612345678, 760.125, 755.5, 641.3, 512.7, 0.4, omni);
  WriteCameraFile(unified, dir_ / "unified.yaml");
  const auto read_unified = ReadCameraFile(dir_ / "unified.yaml");
  ASSERT_EQ(read_unified->type(), CameraModelType::kUnified);
  const auto& u = dynamic_cast<const UnifiedCamera&>(*read_unified);
  EXPECT_EQ(u.width(), 1280);
  EXPECT_EQ(u.height(), 1024);
  EXPECT_EQ(u.xi(), unified.xi());
  EXPECT_EQ(u.fx(), unified.fx());
  EXPECT_EQ(u.fy(), unified.fy());
  EXPECT_EQ(u.cx(), unified.cx());
  EXPECT_EQ(u.cy(), unified.cy());
  EXPECT_EQ(u.skew(), unified.skew());
  EXPECT_EQ(u.distortion().k1, omni.k1);
  EXPECT_EQ(u.distortion().k2, omni.k2);
  EXPECT_EQ(u.distortion().p1, omni.p1);
  EXPECT_EQ(u.distortion().p2, omni.p2);

  WriteCameraFile(EquirectangularCamera(2048, 1024), dir_ / "panorama.yaml");
  const auto panorama = ReadCameraFile(dir_ / "panorama.yaml");
  EXPECT_EQ(panorama->type(), CameraModelType::kEquirectangular);
  EXPECT_EQ(panorama->width(), 2048);
  EXPECT_EQ(panorama->height(), 1024);
}

TEST_F(CameraIoTest, TextRoundTripAndErrorsNameTheSource) {
  const UnifiedCamera camera(800, 600, 0.87, 290.5, 291.25, 401.0, 299.0);
  const std::string yaml = CameraToYaml(camera);
  const auto parsed = ParseCameraText(yaml, "map.db: cameras");
  ASSERT_EQ(parsed->type(), CameraModelType::kUnified);
  EXPECT_EQ(dynamic_cast<const UnifiedCamera&>(*parsed).xi(), 0.87);
  EXPECT_EQ(dynamic_cast<const UnifiedCamera&>(*parsed).fy(), 291.25);
  try {
    ParseCameraText("camera_model: perspective\nimage_width: 10\n", "map.db: cameras");
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "map.db: cameras: missing key 'image_height'");
  }
}

TEST_F(CameraIoTest, WrittenPerspectiveFileIsRosCameraInfo) {
  WriteCameraFile(PerspectiveCamera(640, 480, 500, 501, 320, 240), dir_ / "ros.yaml");
  std::ifstream stream(dir_ / "ros.yaml");
  const std::string text((std::istreambuf_iterator<char>(stream)), std::istreambuf_iterator<char>());
  for (const char* key : {"image_width: 640", "image_height: 480", "camera_name:", "camera_matrix:",
                          "distortion_model: plumb_bob", "distortion_coefficients:", "rectification_matrix:",
                          "projection_matrix:"}) {
    EXPECT_NE(text.find(key), std::string::npos) << key;
  }
  EXPECT_EQ(text.find("camera_model"), std::string::npos);  // plain ROS for the perspective model
}

TEST_F(CameraIoTest, BadFilesGiveOneLineInputErrors) {
  ExpectInputError(dir_ / "does_not_exist.yaml", "file not found");
  ExpectInputError(dir_, "is a directory");
  ExpectInputError(Write("empty.yaml", ""), "empty file");
  ExpectInputError(Write("blank.yaml", "  \n\n"), "empty file");
  std::string junk;
  for (int i = 0; i < 4096; ++i) junk += static_cast<char>((i * 7919 + 13) % 256);
  ExpectInputError(Write("junk.bin", junk), "binary data");
  std::string junk_text;
  for (int i = 0; i < 2048; ++i) junk_text += static_cast<char>(1 + (i * 7919 + 13) % 255);
  try {
    ReadCameraFile(Write("junk.txt", junk_text));
    ADD_FAILURE() << "junk text accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
  }
  ExpectInputError(Write("list.yaml", "- 1\n- 2\n"), "found a list");
  ExpectInputError(Write("scalar.yaml", "hello\n"), "found a plain text");
  ExpectInputError(Write("not_yaml.yaml", "camera_matrix: [1, 2\nimage_width: {\n"), "not valid YAML");
  ExpectInputError(Write("no_k.yaml", "image_width: 640\nimage_height: 480\n"), "missing key 'camera_matrix'");
  ExpectInputError(Write("no_height.yaml", "image_width: 640\ncamera_matrix: [1, 0, 1, 0, 1, 1, 0, 0, 1]\n"),
                   "missing key 'image_height'");
  ExpectInputError(Write("type.yaml", "image_width: wide\nimage_height: 480\n"
                                      "camera_matrix: [1, 0, 1, 0, 1, 1, 0, 0, 1]\n"),
                   "image_width must be a number");
  ExpectInputError(Write("type2.yaml", "image_width: 640\nimage_height: 480\ncamera_matrix: {rows: 3, cols: 3, "
                                       "data: [1, 0, 1, 0, x, 1, 0, 0, 1]}\n"),
                   "must be a number, not 'x'");
  ExpectInputError(Write("type3.yaml", "image_width: 640\nimage_height: 480\ncamera_matrix: 5\n"),
                   "camera_matrix must be a matrix");
  ExpectInputError(Write("size.yaml", "image_width: 640\nimage_height: 480\n"
                                      "camera_matrix: {rows: 2, cols: 2, data: [1, 0, 0, 1]}\n"),
                   "wrong matrix size: camera_matrix is 2x2, expected 3x3");
  ExpectInputError(Write("count.yaml", "image_width: 640\nimage_height: 480\n"
                                       "camera_matrix: {rows: 3, cols: 3, data: [1, 0, 0, 1]}\n"),
                   "camera_matrix says 3x3 but has 4 values");
  ExpectInputError(Write("focal.yaml", "image_width: 640\nimage_height: 480\n"
                                       "camera_matrix: [-500, 0, 320, 0, 500, 240, 0, 0, 1]\n"),
                   "non-positive focal length");
  ExpectInputError(Write("model.yaml", "image_width: 640\nimage_height: 480\n"
                                       "camera_matrix: [500, 0, 320, 0, 500, 240, 0, 0, 1]\n"
                                       "distortion_model: equidistant\ndistortion_coefficients: [0.1, 0, 0, 0]\n"),
                   "unknown distortion model 'equidistant'");
  ExpectInputError(Write("coeffs.yaml", "image_width: 640\nimage_height: 480\n"
                                        "camera_matrix: [500, 0, 320, 0, 500, 240, 0, 0, 1]\n"
                                        "distortion_coefficients: [0.1, 0.2, 0.3]\n"),
                   "distortion_coefficients has 3 values");
  ExpectInputError(Write("camera_model.yaml", "image_width: 640\nimage_height: 480\ncamera_model: kannala\n"
                                              "camera_matrix: [500, 0, 320, 0, 500, 240, 0, 0, 1]\n"),
                   "unknown camera_model 'kannala'");
  ExpectInputError(Write("xi.yaml", "image_width: 640\nimage_height: 480\ncamera_model: unified\n"
                                    "camera_matrix: [500, 0, 320, 0, 500, 240, 0, 0, 1]\n"),
                   "missing key 'xi'");
  ExpectInputError(Write("mismatch.yaml", "image_width: 640\nimage_height: 480\n"
                                          "camera_matrix: [500, 0, 320, 0, 500, 240, 0, 0, 1]\n"),
                   "image size mismatch: file says 640x480, images are 752x480", cv::Size(752, 480));
  ExpectInputError(Write("kitti.txt", "P0: 707 0 601 0 0 707 183 0 0 0 1\n"),
                   "wrong matrix size: P0 has 11 values", cv::Size(1226, 370));
  ExpectInputError(Write("kitti2.txt", "P0: 707 0 601 0 0 707 183 0 0 0 1 zero\n"), "non-numeric value 'zero'",
                   cv::Size(1226, 370));
  ExpectInputError(Write("euroc.yaml", "resolution: [752, 480]\nintrinsics: [458.6, 457.3, 367.2]\n"),
                   "wrong matrix size: intrinsics has 3 values, expected 4");
  ExpectInputError(Write("euroc2.yaml", "resolution: [752, 480]\nintrinsics: [458.6, 457.3, 367.2, 248.3]\n"
                                        "distortion_model: equidistant\ndistortion_coefficients: [0, 0, 0, 0]\n"),
                   "unknown distortion model 'equidistant'");
  ExpectInputError(Write("other.yaml", "foo: 1\nbar: [1, 2]\n"), "missing key 'camera_matrix'");
}

TEST_F(CameraIoTest, MutatedFilesNeverCrash) {
  // Valid files of every YAML flavour, then hundreds of random corruptions: each must either read into a sane
  // camera or throw a one-line InputError, never anything else.
  LensDistortion d;
  d.k1 = -0.2;
  d.p1 = 0.001;
  WriteCameraFile(PerspectiveCamera(640, 480, 500, 501, 320, 240, 0.0, d), dir_ / "p.yaml");
  WriteCameraFile(UnifiedCamera(800, 600, 0.9, 300, 301, 400, 300, 0.0, d), dir_ / "u.yaml");
  std::vector<std::string> bases;
  for (const char* name : {"p.yaml", "u.yaml"}) {
    std::ifstream stream(dir_ / name);
    bases.emplace_back((std::istreambuf_iterator<char>(stream)), std::istreambuf_iterator<char>());
  }
  bases.push_back("%YAML:1.0\n---\nimage_width: 752\nimage_height: 480\ncamera_matrix: !!opencv-matrix\n   rows: 3\n"
                  "   cols: 3\n   dt: d\n   data: [ 458.6, 0., 367.2, 0., 457.3, 248.4, 0., 0., 1. ]\n"
                  "distortion_coefficients: !!opencv-matrix\n   rows: 5\n   cols: 1\n   dt: d\n"
                  "   data: [ -0.28, 0.07, 0.0002, 0.00002, 0. ]\n");
  bases.push_back("resolution: [752, 480]\ncamera_model: pinhole\nintrinsics: [458.654, 457.296, 367.215, 248.375]\n"
                  "distortion_model: radial-tangential\ndistortion_coefficients: [-0.28, 0.07, 0.0002, 1.7e-05]\n");
  bases.push_back("<?xml version=\"1.0\"?>\n<opencv_storage>\n<image_width>640</image_width>\n"
                  "<image_height>480</image_height>\n<camera_matrix type_id=\"opencv-matrix\">\n  <rows>3</rows>\n"
                  "  <cols>3</cols>\n  <dt>d</dt>\n  <data>\n    500. 0. 320. 0. 500. 240. 0. 0. 1.</data></camera_matrix>\n"
                  "<distortion_coefficients type_id=\"opencv-matrix\">\n  <rows>5</rows>\n  <cols>1</cols>\n"
                  "  <dt>d</dt>\n  <data>\n    -0.2 0.05 0. 0. 0.01</data></distortion_coefficients>\n"
                  "</opencv_storage>\n");
  bases.push_back("P0: 7.07e+02 0 6.01e+02 0 0 7.07e+02 1.83e+02 0 0 0 1 0\nP1: 1 2 3\n");
  const std::string alphabet = "0123456789.-+eE:[]{},#!&*|<>/='\"\n\t abcxyz_\\%";
  std::mt19937 rng(9);
  int accepted = 0, rejected = 0;
  for (int trial = 0; trial < 600; ++trial) {
    std::string text = bases[trial % bases.size()];
    const int edits = 1 + trial % 4;
    for (int e = 0; e < edits && !text.empty(); ++e) {
      const size_t at = rng() % text.size();
      switch (rng() % 4) {
        case 0: text[at] = alphabet[rng() % alphabet.size()]; break;
        case 1: text.erase(at, 1 + rng() % 12); break;
        case 2: text.insert(at, text.substr(rng() % text.size(), 1 + rng() % 12)); break;
        default: text.resize(at); break;
      }
    }
    const auto path = Write("fuzz.yaml", text);
    try {
      const auto camera = ReadCameraFile(path, trial % 5 == 4 ? std::optional<cv::Size>(cv::Size(1226, 370))
                                                              : std::nullopt);
      ++accepted;
      EXPECT_GT(camera->width(), 0);
      EXPECT_GT(camera->height(), 0);
      EXPECT_TRUE(std::isfinite(camera->FocalLength()) && camera->FocalLength() > 0.0) << text;
    } catch (const InputError& e) {
      ++rejected;
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
    } catch (const std::exception& e) {
      ADD_FAILURE() << "unexpected exception " << e.what() << " for:\n" << text;
    }
  }
  std::printf("mutated files: %d accepted, %d rejected with InputError\n", accepted, rejected);
  EXPECT_GT(rejected, 200);
  EXPECT_GT(accepted, 20);
}

}  // namespace
}  // namespace retrace
