#include "retrace/ros/bag_sequence.h"

#include <fstream>

#include <fmt/format.h>
#include <geometry_msgs/PoseStamped.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include "retrace/camera/camera_checks.h"
#include "retrace/camera/camera_io.h"
#include "retrace/camera/perspective_camera.h"
#include "retrace/camera/unified_camera.h"
#include "retrace/dataset/ground_truth.h"
#include "retrace/ros/messages.h"
#include "retrace/sim/recording.h"
#include "retrace/util/error.h"
#include "retrace/util/testing.h"

namespace retrace {
namespace {

namespace fs = std::filesystem;

using retrace::testing::ErrorOf;

std::vector<Frame> ReadAll(Sequence& sequence) {
  std::vector<Frame> frames;
  while (std::optional<Frame> frame = sequence.Next()) frames.push_back(*frame);
  return frames;
}

// A recognisable colour test frame: background level 20 + 10 i with a square whose position depends on i, its
// three channels different.
cv::Mat TestImage(int i, cv::Size size = cv::Size(64, 48)) {
  cv::Mat image(size, CV_8UC3, cv::Scalar(20 + 10 * i, 40 + 5 * i, 90));
  cv::rectangle(image, cv::Rect(2 + 3 * i, 10, 12, 12), cv::Scalar(250, 30, 120), cv::FILLED);
  return image;
}

sensor_msgs::CameraInfo TestCameraInfo(cv::Size size = cv::Size(64, 48)) {
  const PerspectiveCamera camera(size.width, size.height, 50.0, 51.0, 31.5, 23.5, 0.0, LensDistortion{-0.1, 0.01});
  return CameraToCameraInfo(camera, ros::Time(1, 0), "camera");
}

// A small bag written by hand: `count` frames on `topic` as `encoding` (mono8, bgr8, rgb8, or "png" / "jpeg" for
// CompressedImage), 0.1 s apart from t = 5 s, and a CameraInfo on /cam/camera_info.
void WriteTestBag(const fs::path& path, const std::string& topic, const std::string& encoding, int count = 3) {
  rosbag::Bag bag;
  bag.open(path.string(), rosbag::bagmode::Write);
  for (int i = 0; i < count; ++i) {
    const ros::Time stamp = SecondsToRosTime(5.0 + 0.1 * i);
    const cv::Mat bgr = TestImage(i);
    if (encoding == "png" || encoding == "jpeg") {
      sensor_msgs::CompressedImage message;
      message.header.stamp = stamp;
      message.format = encoding;
      cv::imencode("." + encoding, bgr, message.data);
      bag.write(topic, stamp, message);
    } else {
      sensor_msgs::Image message = ImageToMessage(bgr, stamp, "camera");
      message.encoding = encoding;
      if (encoding == "rgb8") {
        cv::Mat rgb;
        cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
        message = ImageToMessage(rgb, stamp, "camera");
        message.encoding = "rgb8";
      } else if (encoding == "mono8") {
        cv::Mat gray;
        cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
        message = ImageToMessage(gray, stamp, "camera");
      }
      bag.write(topic, stamp, message);
    }
    bag.write("/cam/camera_info", stamp, TestCameraInfo());
  }
  bag.close();
}

cv::Mat Gray(const cv::Mat& bgr) {
  cv::Mat gray;
  cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
  return gray;
}

// The round trip of the issue: `sim render --bag` and the folder render of the same scenario read back as the same
// frames, timestamps, camera and ground truth.
TEST(BagSequence, SimulatedDriveReadsBackAsTheFolderRender) {
  Scenario scenario;
  scenario.town.blocks_x = 2;
  scenario.town.blocks_y = 2;
  scenario.route.segments = 2;
  scenario.camera.width = 320;
  scenario.camera.height = 240;
  scenario.num_frames = 25;
  const fs::path dir = testing::MakeTempDir("bag_round_trip");
  RecordOptions options;
  options.progress = false;
  Simulator for_folder(scenario);
  RecordSequence(&for_folder, dir / "folder", options);
  Simulator for_bag(scenario);
  const RecordSummary summary = RecordBag(&for_bag, dir / "drive.bag", options);
  ASSERT_EQ(summary.frames, 25);

  std::unique_ptr<Sequence> folder = OpenSequence(dir / "folder");
  std::unique_ptr<BagSequence> bag = OpenBagSequence(dir / "drive.bag");  // the bag's only image topic
  EXPECT_EQ(bag->layout(), "rosbag");
  EXPECT_EQ(bag->topic(), "/camera/image_raw");
  EXPECT_EQ(bag->camera_topic(), "/camera/camera_info");
  ASSERT_EQ(bag->size(), folder->size());
  const std::vector<Frame> expected = ReadAll(*folder);
  const std::vector<Frame> frames = ReadAll(*bag);
  ASSERT_EQ(frames.size(), expected.size());
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(frames[i].index, i);
    EXPECT_EQ(frames[i].name, fmt::format("frame_{:06d}", i));
    EXPECT_NEAR(frames[i].timestamp, expected[i].timestamp, 1e-6) << i;
    ASSERT_EQ(frames[i].image.type(), CV_8UC1);
    EXPECT_EQ(cv::norm(frames[i].image, expected[i].image, cv::NORM_INF), 0.0) << "frame " << i;
  }
  // Random access gives the streamed frames.
  Frame frame;
  ASSERT_TRUE(bag->Read(7, &frame));
  EXPECT_EQ(cv::norm(frame.image, expected[7].image, cv::NORM_INF), 0.0);
  EXPECT_FALSE(bag->Read(frames.size(), &frame));

  // The camera: the CameraInfo images the same rays as the folder's camera.yaml.
  const std::unique_ptr<CameraModel> camera = bag->camera();
  ASSERT_TRUE(camera);
  const std::unique_ptr<CameraModel> folder_camera = ReadCameraFile(dir / "folder" / "camera.yaml");
  EXPECT_EQ(camera->model_name(), folder_camera->model_name());
  EXPECT_EQ(camera->width(), folder_camera->width());
  EXPECT_EQ(camera->height(), folder_camera->height());
  EXPECT_LT(CameraProjectionDifferencePx(*camera, *folder_camera), 1e-6);

  // The ground truth: one PoseStamped per frame, the poses of poses.txt.
  const std::vector<TimedPose> truth = ReadKittiPoses(dir / "folder" / "poses.txt");
  rosbag::Bag raw;
  raw.open((dir / "drive.bag").string(), rosbag::bagmode::Read);
  std::vector<geometry_msgs::PoseStamped> poses;
  for (const rosbag::MessageInstance& m : rosbag::View(raw, rosbag::TopicQuery("/ground_truth/pose"))) {
    poses.push_back(*m.instantiate<geometry_msgs::PoseStamped>());
  }
  ASSERT_EQ(poses.size(), truth.size());
  for (size_t i = 0; i < poses.size(); ++i) {
    const geometry_msgs::Pose& p = poses[i].pose;
    const Eigen::Quaterniond q(p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z);
    EXPECT_NEAR(poses[i].header.stamp.toSec(), frames[i].timestamp, 1e-9);
    EXPECT_EQ(poses[i].header.frame_id, "world");
    EXPECT_LT((Vector3d(p.position.x, p.position.y, p.position.z) - truth[i].world_from_cam.translation).norm(), 1e-6);
    EXPECT_LT(RotationErrorDeg(q.toRotationMatrix(), truth[i].world_from_cam.rotation), 1e-4);
  }
  fs::remove_all(dir);
}

TEST(BagSequence, EncodingsAndCompressedImages) {
  const fs::path dir = testing::MakeTempDir("bag_encodings");
  for (const std::string encoding : {"mono8", "bgr8", "rgb8", "png", "jpeg"}) {
    SCOPED_TRACE(encoding);
    const fs::path path = dir / (encoding + ".bag");
    const bool compressed = encoding == "png" || encoding == "jpeg";
    WriteTestBag(path, compressed ? "/cam/image_raw/compressed" : "/cam/image_raw", encoding);
    std::unique_ptr<BagSequence> sequence = OpenBagSequence(path);
    // A compressed transport's sibling camera_info is found too.
    EXPECT_EQ(sequence->camera_topic(), "/cam/camera_info");
    const std::vector<Frame> frames = ReadAll(*sequence);
    ASSERT_EQ(frames.size(), 3u);
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(frames[i].timestamp, 5.0 + 0.1 * i, 1e-9);
      // Every lossless encoding gives the gray image of the BGR original (rgb8 too: its channels are swapped
      // back); JPEG within its compression error.
      const double error = cv::norm(frames[i].image, Gray(TestImage(i)), cv::NORM_INF);
      if (encoding == "jpeg") {
        EXPECT_LT(error, 30.0);
        EXPECT_LT(cv::norm(frames[i].image, Gray(TestImage(i)), cv::NORM_L1) / frames[i].image.total(), 3.0);
      } else {
        EXPECT_EQ(error, 0.0) << "frame " << i;
      }
    }
    const std::unique_ptr<CameraModel> camera = sequence->camera();
    ASSERT_TRUE(camera);
    const auto* perspective = dynamic_cast<const PerspectiveCamera*>(camera.get());
    ASSERT_TRUE(perspective);
    EXPECT_EQ(perspective->fx(), 50.0);
    EXPECT_EQ(perspective->fy(), 51.0);
    EXPECT_EQ(perspective->cx(), 31.5);
    EXPECT_EQ(perspective->distortion().k1, -0.1);
    EXPECT_EQ(perspective->distortion().k2, 0.01);
  }
  fs::remove_all(dir);
}

TEST(BagSequence, CameraInfoDistortionModels) {
  sensor_msgs::CameraInfo info = TestCameraInfo();
  // The round trip of a perspective camera: every number kept.
  std::unique_ptr<CameraModel> camera = CameraFromCameraInfo(info, "test");
  const auto* perspective = dynamic_cast<const PerspectiveCamera*>(camera.get());
  ASSERT_TRUE(perspective);
  EXPECT_EQ(perspective->fx(), 50.0);
  EXPECT_EQ(perspective->cy(), 23.5);
  EXPECT_EQ(perspective->distortion().k2, 0.01);
  // rational_polynomial with k4..k6 = 0 is plumb_bob; with k4 != 0 it has no retrace model.
  info.distortion_model = "rational_polynomial";
  info.D = {-0.1, 0.01, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  camera = CameraFromCameraInfo(info, "test");
  EXPECT_EQ(dynamic_cast<const PerspectiveCamera&>(*camera).distortion().k1, -0.1);
  info.D[5] = 0.2;
  EXPECT_EQ(ErrorOf([&] { CameraFromCameraInfo(info, "test"); }),
            "test: D has non-zero rational/thin-prism terms (k4..), which retrace does not support");
  // No model and no coefficients: a pinhole camera.
  info.distortion_model = "";
  info.D.clear();
  camera = CameraFromCameraInfo(info, "test");
  EXPECT_TRUE(dynamic_cast<const PerspectiveCamera&>(*camera).distortion().IsZero());
  // Binning or a region of interest: the images are not the calibrated ones.
  info.binning_x = 2;
  EXPECT_EQ(ErrorOf([&] { CameraFromCameraInfo(info, "test"); }),
            "test: CameraInfo with binning 2x0 is not supported (the images are not the calibrated ones)");
  info.binning_x = 0;
  info.roi.width = 32;
  info.roi.height = 24;
  EXPECT_EQ(ErrorOf([&] { CameraFromCameraInfo(info, "test"); }),
            "test: CameraInfo with a region of interest is not supported (the images are not the calibrated ones)");
  // Only perspective cameras have a CameraInfo.
  const UnifiedCamera fisheye(64, 48, 0.9, 60.0, 60.0, 31.5, 23.5);
  EXPECT_EQ(ErrorOf([&] { CameraToCameraInfo(fisheye, ros::Time(), "camera"); }),
            "a unified camera has no sensor_msgs/CameraInfo distortion model (only perspective cameras can be written "
            "to a bag)");
}

TEST(BagSequence, TopicsAreChosenAndNamed) {
  EXPECT_EQ(SiblingCameraInfoTopic("/camera/image_raw"), "/camera/camera_info");
  EXPECT_EQ(SiblingCameraInfoTopic("/camera/image_raw/compressed"), "/camera/camera_info");
  EXPECT_EQ(SiblingCameraInfoTopic("/image"), "/camera_info");
  EXPECT_TRUE(IsBagPath("a/run.bag"));
  EXPECT_FALSE(IsBagPath("a/run.mp4"));

  const fs::path dir = testing::MakeTempDir("bag_topics");
  const fs::path path = dir / "two.bag";
  {
    rosbag::Bag bag;
    bag.open(path.string(), rosbag::bagmode::Write);
    for (int i = 0; i < 2; ++i) {
      const ros::Time stamp(10 + i, 0);
      bag.write("/left/image", stamp, ImageToMessage(Gray(TestImage(i)), stamp, "left"));
      bag.write("/right/image", stamp, ImageToMessage(Gray(TestImage(i + 5)), ros::Time(), "right"));
      geometry_msgs::PoseStamped pose;
      bag.write("/pose", stamp, pose);
    }
  }
  // Several image topics: one must be chosen.
  EXPECT_EQ(ErrorOf([&] { OpenBagSequence(path); }),
            path.string() + ": holds 2 image topics (/left/image, /right/image): choose one with --topic");
  // A topic given without its leading slash is the absolute one.
  std::unique_ptr<BagSequence> right = OpenBagSequence(path, {"right/image", ""});
  EXPECT_EQ(right->topic(), "/right/image");
  EXPECT_TRUE(right->camera_topic().empty());
  EXPECT_FALSE(right->camera());
  const std::vector<Frame> frames = ReadAll(*right);
  ASSERT_EQ(frames.size(), 2u);
  // Header stamps of zero: the record time.
  EXPECT_EQ(frames[1].timestamp, 11.0);
  EXPECT_EQ(cv::norm(frames[1].image, Gray(TestImage(6)), cv::NORM_INF), 0.0);
  fs::remove_all(dir);
}

TEST(BagSequence, BadInputGivesOneLineErrorsNamingTheBag) {
  const fs::path dir = testing::MakeTempDir("bag_errors");
  const std::string missing = (dir / "missing.bag").string();
  EXPECT_EQ(ErrorOf([&] { OpenBagSequence(missing); }), missing + ": no such file");

  const fs::path text = dir / "text.bag";
  std::ofstream(text) << "not a bag\n";
  const std::string not_bag = ErrorOf([&] { OpenBagSequence(text); });
  EXPECT_EQ(not_bag.rfind(text.string() + ": not a readable ROS bag (", 0), 0u) << not_bag;
  EXPECT_EQ(not_bag.find('\n'), std::string::npos);

  // A bag cut short (a recording that crashed): refused, not a crash.
  const fs::path good = dir / "good.bag";
  WriteTestBag(good, "/cam/image_raw", "mono8", 3);
  const fs::path cut = dir / "cut.bag";
  {
    std::ifstream in(good, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  }
  const std::string cut_error = ErrorOf([&] { OpenBagSequence(cut); });
  EXPECT_EQ(cut_error.rfind(cut.string() + ": ", 0), 0u) << cut_error;

  EXPECT_EQ(ErrorOf([&] { OpenBagSequence(good, {"/cam/image", ""}); }),
            good.string() + ": no topic /cam/image in the bag (image topics: /cam/image_raw)");
  EXPECT_EQ(ErrorOf([&] { OpenBagSequence(good, {"/cam/camera_info", ""}); }),
            good.string() + ": topic /cam/camera_info carries sensor_msgs/CameraInfo, not sensor_msgs/Image or "
                            "sensor_msgs/CompressedImage");
  EXPECT_EQ(ErrorOf([&] { OpenBagSequence(good, {"", "/cam/info"}); }),
            good.string() + ": no topic /cam/info in the bag");

  const fs::path bayer = dir / "bayer.bag";
  WriteTestBag(bayer, "/cam/image_raw", "bayer_rggb8");
  EXPECT_EQ(ErrorOf([&] { OpenBagSequence(bayer); }),
            bayer.string() + ": /cam/image_raw: image encoding 'bayer_rggb8' is not supported (supported: mono8, "
                             "bgr8, rgb8, or sensor_msgs/CompressedImage)");

  // A fisheye CameraInfo has no retrace model; an uncalibrated one is refused.
  const fs::path fisheye = dir / "fisheye.bag";
  {
    rosbag::Bag bag;
    bag.open(fisheye.string(), rosbag::bagmode::Write);
    const ros::Time stamp(1, 0);
    bag.write("/cam/image_raw", stamp, ImageToMessage(Gray(TestImage(0)), stamp, "camera"));
    sensor_msgs::CameraInfo info = TestCameraInfo();
    info.distortion_model = "equidistant";
    info.D = {0.1, 0.01, 0.0, 0.0};
    bag.write("/cam/camera_info", stamp, info);
    info.K.fill(0.0);
    bag.write("/uncalibrated/camera_info", stamp, info);
  }
  const std::string equidistant = ErrorOf([&] { OpenBagSequence(fisheye)->camera(); });
  EXPECT_EQ(equidistant.rfind(fisheye.string() + ": /cam/camera_info: ", 0), 0u) << equidistant;
  EXPECT_NE(equidistant.find("equidistant"), std::string::npos) << equidistant;
  EXPECT_EQ(ErrorOf([&] { OpenBagSequence(fisheye, {"", "/uncalibrated/camera_info"})->camera(); }),
            fisheye.string() + ": /uncalibrated/camera_info: uncalibrated camera (CameraInfo K is all zeros); give "
                               "a calibration file");
  fs::remove_all(dir);
}

TEST(BagSequence, DamagedFramesAreSkippedAndSizeChangesRefused) {
  const fs::path dir = testing::MakeTempDir("bag_frames");
  const fs::path path = dir / "frames.bag";
  {
    rosbag::Bag bag;
    bag.open(path.string(), rosbag::bagmode::Write);
    for (int i = 0; i < 4; ++i) {
      const ros::Time stamp(20 + i, 0);
      sensor_msgs::CompressedImage message;
      message.header.stamp = stamp;
      message.format = "png";
      cv::imencode(".png", TestImage(i, i == 3 ? cv::Size(32, 24) : cv::Size(64, 48)), message.data);
      if (i == 1) message.data.resize(message.data.size() / 3);  // a frame damaged in transit
      bag.write("/cam/image_raw/compressed", stamp, message);
    }
  }
  std::unique_ptr<BagSequence> sequence = OpenBagSequence(path);
  std::optional<Frame> frame = sequence->Next();
  ASSERT_TRUE(frame);
  EXPECT_EQ(frame->index, 0u);
  frame = sequence->Next();
  ASSERT_TRUE(frame);
  EXPECT_EQ(frame->index, 2u);  // frame 1 skipped
  ASSERT_EQ(sequence->skipped().size(), 1u);
  EXPECT_EQ(sequence->skipped()[0], "frame_000001");
  EXPECT_EQ(ErrorOf([&] { sequence->Next(); }),
            path.string() + ": /cam/image_raw/compressed message 3: image is 32x24 but the sequence's first frame is "
                            "64x48 (all frames of a sequence must come from one camera at one size)");
  fs::remove_all(dir);
}

}  // namespace
}  // namespace retrace
