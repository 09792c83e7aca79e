#include "retrace/dataset/sequence.h"

#include <fstream>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "retrace/dataset/ground_truth.h"
#include "retrace/dataset/kitti_writer.h"
#include "retrace/dataset/text_io.h"
#include "retrace/util/error.h"
#include "retrace/util/testing.h"

namespace retrace {
namespace {

namespace fs = std::filesystem;

void WriteText(const fs::path& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
}

// A recognisable test frame: uniform level 20 + 10 i with a white square whose position depends on i.
cv::Mat TestImage(int i, cv::Size size = cv::Size(64, 48), int type = CV_8UC1) {
  cv::Mat image(size, type, cv::Scalar::all(20 + 10 * i));
  cv::rectangle(image, cv::Rect(2 + 3 * i, 10, 12, 12), cv::Scalar::all(255), cv::FILLED);
  return image;
}

// Level of the background (top-right corner, never covered by the square).
int Level(const cv::Mat& image) { return image.at<uint8_t>(0, image.cols - 1); }

using retrace::testing::ErrorOf;

std::vector<Frame> ReadAll(Sequence& sequence) {
  std::vector<Frame> frames;
  while (std::optional<Frame> frame = sequence.Next()) frames.push_back(*frame);
  return frames;
}

TEST(Sequence, KittiRealSequence07) {
  RETRACE_REQUIRE_SHARED_DATA(dir, "kitti07");
  std::unique_ptr<Sequence> sequence = OpenSequence(dir);
  EXPECT_EQ(sequence->layout(), "kitti");
  ASSERT_EQ(sequence->size(), 160u);
  EXPECT_EQ(sequence->image_size(), cv::Size(1226, 370));
  ASSERT_TRUE(sequence->calibration_file());
  EXPECT_EQ(sequence->calibration_file()->filename(), "calib.txt");
  ASSERT_TRUE(sequence->ground_truth_file());
  EXPECT_EQ(*sequence->ground_truth_file(), dir / "poses.txt");
  const std::vector<double> times = ReadTimestamps(dir / "times.txt");
  const std::vector<Frame> frames = ReadAll(*sequence);
  ASSERT_EQ(frames.size(), 160u);
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(frames[i].index, i);
    EXPECT_EQ(frames[i].timestamp, times[i]);
    EXPECT_EQ(frames[i].image.type(), CV_8UC1);
    EXPECT_EQ(frames[i].image.size(), cv::Size(1226, 370));
  }
  EXPECT_EQ(frames[42].name, "000042.png");
  // Pixels are the file's pixels.
  const cv::Mat direct = cv::imread((dir / "image_0" / "000042.png").string(), cv::IMREAD_GRAYSCALE);
  EXPECT_EQ(cv::norm(direct, frames[42].image, cv::NORM_INF), 0.0);
  EXPECT_TRUE(sequence->skipped().empty());

  // The image_0 folder itself opens the same sequence.
  std::unique_ptr<Sequence> from_images = OpenSequence(dir / "image_0");
  EXPECT_EQ(from_images->layout(), "kitti");
  EXPECT_EQ(from_images->size(), 160u);
  Frame frame;
  ASSERT_TRUE(from_images->Read(159, &frame));
  EXPECT_EQ(frame.timestamp, times[159]);
  EXPECT_FALSE(from_images->Read(160, &frame));
}

TEST(Sequence, EurocRealClip) {
  RETRACE_REQUIRE_SHARED_DATA(dir, "euroc_v101_clip");
  for (const fs::path& path : {dir, dir / "mav0", dir / "mav0" / "cam0"}) {
    std::unique_ptr<Sequence> sequence = OpenSequence(path);
    EXPECT_EQ(sequence->layout(), "euroc") << path;
    EXPECT_EQ(sequence->size(), 95u) << path;
    EXPECT_EQ(sequence->path(), dir / "mav0" / "cam0") << path;
  }
  std::unique_ptr<Sequence> sequence = OpenSequence(dir);
  EXPECT_EQ(sequence->image_size(), cv::Size(752, 480));
  ASSERT_TRUE(sequence->calibration_file());
  EXPECT_EQ(*sequence->calibration_file(), dir / "mav0" / "cam0" / "sensor.yaml");
  // The clip has no ground-truth csv (see its README).
  EXPECT_FALSE(sequence->ground_truth_file());
  const std::vector<Frame> frames = ReadAll(*sequence);
  ASSERT_EQ(frames.size(), 95u);
  EXPECT_NEAR(frames.front().timestamp, 1403715273.262142976, 1e-6);
  EXPECT_NEAR(frames.back().timestamp, 1403715277.962142976, 1e-6);
  EXPECT_EQ(frames.front().name, "1403715273262142976.png");
  for (size_t i = 1; i < frames.size(); ++i) {
    EXPECT_NEAR(frames[i].timestamp - frames[i - 1].timestamp, 0.05, 1e-3);  // 20 Hz
  }
  EXPECT_TRUE(sequence->skipped().empty());

  // cam1/data.csv lists 99 rows but only 95 images exist: 4 frames reported and skipped.
  std::unique_ptr<Sequence> cam1 = OpenSequence(dir / "mav0" / "cam1");
  EXPECT_EQ(cam1->size(), 99u);
  EXPECT_EQ(ReadAll(*cam1).size(), 95u);
  EXPECT_EQ(cam1->skipped().size(), 4u);
}

TEST(Sequence, FrameOfAnotherSizeIsAnError) {
  const fs::path dir = testing::MakeTempDir("seq_mixed_size");
  for (int i = 0; i < 4; ++i) {
    const cv::Size size = i == 2 ? cv::Size(80, 48) : cv::Size(64, 48);
    ASSERT_TRUE(cv::imwrite((dir / fmt::format("{:02d}.png", i)).string(), TestImage(i, size)));
  }
  std::unique_ptr<Sequence> sequence = OpenSequence(dir);
  EXPECT_EQ(sequence->image_size(), cv::Size(64, 48));
  ASSERT_TRUE(sequence->Next());
  ASSERT_TRUE(sequence->Next());
  // Neither resized nor skipped: the frame names its file and both sizes.
  const std::string message = ErrorOf([&] { sequence->Next(); });
  EXPECT_NE(message.find("02.png: image is 80x48 but the sequence's first frame is 64x48"), std::string::npos)
      << message;
  Frame frame;
  EXPECT_TRUE(sequence->Read(3, &frame));
  EXPECT_NE(ErrorOf([&] { sequence->Read(2, &frame); }).find("80x48"), std::string::npos);
  fs::remove_all(dir);
}

TEST(Sequence, FolderWithAndWithoutTimes) {
  const fs::path dir = testing::MakeTempDir("seq_folder");
  // Colour images in mixed formats, sorted by name.
  const std::vector<std::string> names = {"a.png", "b.jpg", "c.bmp", "d.png", "e.tif"};
  for (int i = 0; i < 5; ++i) {
    ASSERT_TRUE(cv::imwrite((dir / names[i]).string(), TestImage(i, cv::Size(64, 48), CV_8UC3)));
  }
  WriteText(dir / "notes.txt", "not an image\n");
  SequenceOptions options;
  options.frame_rate = 10;
  std::unique_ptr<Sequence> sequence = OpenSequence(dir, options);
  EXPECT_EQ(sequence->layout(), "folder");
  EXPECT_EQ(sequence->size(), 5u);
  EXPECT_FALSE(sequence->calibration_file());
  EXPECT_FALSE(sequence->ground_truth_file());
  std::vector<Frame> frames = ReadAll(*sequence);
  ASSERT_EQ(frames.size(), 5u);
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(frames[i].name, names[i]);
    EXPECT_DOUBLE_EQ(frames[i].timestamp, 0.1 * i);
    EXPECT_EQ(frames[i].image.type(), CV_8UC1);
    EXPECT_NEAR(Level(frames[i].image), 20 + 10 * i, 2);  // jpg is lossy
  }
  // Rewind restarts.
  sequence->Rewind();
  ASSERT_TRUE(sequence->Next());

  WriteText(dir / "times.txt", "5.0\n5.5\n6.0\n6.5\n7.25\n");
  WriteText(dir / "camera.yaml", "model: perspective\n");
  sequence = OpenSequence(dir);
  frames = ReadAll(*sequence);
  ASSERT_EQ(frames.size(), 5u);
  EXPECT_EQ(frames[4].timestamp, 7.25);
  EXPECT_EQ(*sequence->calibration_file(), dir / "camera.yaml");

  WriteText(dir / "times.txt", "5.0\n5.5\n6.0\n");
  std::string message = ErrorOf([&] { OpenSequence(dir); });
  EXPECT_NE(message.find("times.txt: has 3 lines but the folder holds 5 images"), std::string::npos) << message;
  WriteText(dir / "times.txt", "5.0\n5.5\nsix\n6.5\n7\n");
  message = ErrorOf([&] { OpenSequence(dir); });
  EXPECT_NE(message.find("times.txt: line 3: 'six' is not a number"), std::string::npos) << message;
  fs::remove_all(dir);
}

TEST(Sequence, StructuralErrorsThrow) {
  const fs::path dir = testing::MakeTempDir("seq_errors");
  std::string message = ErrorOf([&] { OpenSequence(dir / "nothing_here"); });
  EXPECT_NE(message.find("nothing_here: no such file or folder"), std::string::npos) << message;
  message = ErrorOf([&] { OpenSequence(dir); });
  EXPECT_NE(message.find("no images"), std::string::npos) << message;
  WriteText(dir / "not_a_video.avi", "hello");
  message = ErrorOf([&] { OpenSequence(dir / "not_a_video.avi"); });
  EXPECT_NE(message.find("not_a_video.avi: cannot be opened as a video"), std::string::npos) << message;

  // EuRoC with a garbage csv.
  fs::create_directories(dir / "mav0" / "cam0" / "data");
  WriteText(dir / "mav0" / "cam0" / "data.csv", "#timestamp [ns],filename\n100,100.png\n2OO,200.png\n");
  message = ErrorOf([&] { OpenSequence(dir); });
  EXPECT_NE(message.find("data.csv: line 3: '2OO' is not a timestamp"), std::string::npos) << message;
  WriteText(dir / "mav0" / "cam0" / "data.csv", "#timestamp [ns],filename\n100 100.png\n");
  message = ErrorOf([&] { OpenSequence(dir); });
  EXPECT_NE(message.find("line 2: expected 'timestamp [ns],filename'"), std::string::npos) << message;
  WriteText(dir / "mav0" / "cam0" / "data.csv", "#timestamp [ns],filename\n");
  message = ErrorOf([&] { OpenSequence(dir); });
  EXPECT_NE(message.find("data.csv: lists no frames"), std::string::npos) << message;
  fs::remove_all(dir);
}

TEST(Sequence, CorruptImageIsReportedOnceAndSkipped) {
  const fs::path dir = testing::MakeTempDir("seq_corrupt");
  for (int i = 0; i < 4; ++i) ASSERT_TRUE(cv::imwrite((dir / ("f" + std::to_string(i) + ".png")).string(), TestImage(i)));
  // Frame 2: a PNG signature followed by garbage.
  WriteText(dir / "f2.png", std::string("\x89PNG\r\n\x1a\n", 8) + "garbage garbage garbage");
  std::unique_ptr<Sequence> sequence = OpenSequence(dir);
  EXPECT_EQ(sequence->size(), 4u);
  std::vector<Frame> frames = ReadAll(*sequence);
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[0].index, 0u);
  EXPECT_EQ(frames[1].index, 1u);
  EXPECT_EQ(frames[2].index, 3u);
  EXPECT_EQ(Level(frames[2].image), 50);
  ASSERT_EQ(sequence->skipped(), std::vector<std::string>{"f2.png"});
  Frame frame;
  EXPECT_FALSE(sequence->Read(2, &frame));
  sequence->Rewind();
  EXPECT_EQ(ReadAll(*sequence).size(), 3u);
  EXPECT_EQ(sequence->skipped().size(), 1u);  // reported once
  fs::remove_all(dir);
}

TEST(Sequence, KittiWriterRoundTripAndMissingFrames) {
  const fs::path dir = testing::MakeTempDir("seq_kitti");
  std::vector<TimedPose> poses;
  {
    KittiSequenceWriter writer(dir / "seq");
    Matrix34d p0;
    p0 << 700.5, 0, 320.25, 0, 0, 701, 240.125, 0, 0, 0, 1, 0;
    writer.WriteCalibration(p0);
    for (int i = 0; i < 6; ++i) {
      const Rigid3d pose(Eigen::AngleAxisd(0.1 * i, Vector3d::UnitY()).toRotationMatrix(),
                         Vector3d(0.01 * i, 0, 1.3 * i));
      poses.push_back({1234.5 + 0.1 * i, pose});
      writer.WriteFrame(TestImage(i), poses.back().timestamp, pose);
    }
    EXPECT_EQ(writer.frames_written(), 6u);
  }
  std::unique_ptr<Sequence> sequence = OpenSequence(dir / "seq");
  EXPECT_EQ(sequence->layout(), "kitti");
  EXPECT_EQ(sequence->size(), 6u);
  EXPECT_EQ(*sequence->calibration_file(), dir / "seq" / "calib.txt");
  EXPECT_EQ(*sequence->ground_truth_file(), dir / "seq" / "poses.txt");
  std::vector<Frame> frames = ReadAll(*sequence);
  ASSERT_EQ(frames.size(), 6u);
  for (int i = 0; i < 6; ++i) {
    EXPECT_EQ(frames[i].timestamp, poses[i].timestamp);
    EXPECT_EQ(cv::norm(frames[i].image, TestImage(i), cv::NORM_INF), 0.0);
  }
  const std::vector<TimedPose> read = ReadKittiPoses(dir / "seq" / "poses.txt", dir / "seq" / "times.txt");
  ASSERT_EQ(read.size(), 6u);
  for (int i = 0; i < 6; ++i) {
    EXPECT_EQ(read[i].timestamp, poses[i].timestamp);
    EXPECT_EQ(read[i].world_from_cam.translation, poses[i].world_from_cam.translation);
    EXPECT_LT((read[i].world_from_cam.rotation - poses[i].world_from_cam.rotation).cwiseAbs().maxCoeff(), 1e-15);
  }
  const std::vector<TextLine> calib = ReadTextLines(dir / "seq" / "calib.txt");
  ASSERT_EQ(calib.size(), 4u);
  EXPECT_EQ(calib[0].text, "P0: 700.5 0 320.25 0 0 701 240.125 0 0 0 1 0");
  EXPECT_EQ(calib[3].text, "P3: 700.5 0 320.25 0 0 701 240.125 0 0 0 1 0");

  // Frames 1 and 4 missing: skipped with their names, the others read with their own timestamps.
  fs::remove(dir / "seq" / "image_0" / "000001.png");
  fs::remove(dir / "seq" / "image_0" / "000004.png");
  sequence = OpenSequence(dir / "seq");
  EXPECT_EQ(sequence->size(), 6u);
  frames = ReadAll(*sequence);
  ASSERT_EQ(frames.size(), 4u);
  EXPECT_EQ(frames[1].index, 2u);
  EXPECT_EQ(frames[1].timestamp, poses[2].timestamp);
  EXPECT_EQ(sequence->skipped(), (std::vector<std::string>{"000001.png", "000004.png"}));

  // An image beyond the lines of times.txt is a broken layout.
  WriteText(dir / "seq" / "times.txt", "0\n0.1\n");
  const std::string message = ErrorOf([&] { OpenSequence(dir / "seq"); });
  EXPECT_NE(message.find("times.txt: has 2 lines but image_0 holds frame 000002.png"), std::string::npos) << message;

  // A writer that cannot create its folder (a file is in the way) names it.
  WriteText(dir / "blocker", "x");
  const std::string writer_error = ErrorOf([&] { KittiSequenceWriter writer(dir / "blocker"); });
  EXPECT_NE(writer_error.find("blocker"), std::string::npos) << writer_error;
  fs::remove_all(dir);
}

// KITTI's colour download has image_2 and image_3 only: the left colour camera is read (in grey), with calib.txt's
// P2; a folder with image_0 keeps the grey camera, and an image_N folder given opens camera N.
TEST(Sequence, KittiColourAndRightCameras) {
  const fs::path dir = testing::MakeTempDir("seq_kitti_colour");
  const fs::path root = dir / "seq";
  fs::create_directories(root / "image_2");
  fs::create_directories(root / "image_3");
  for (int i = 0; i < 3; ++i) {
    cv::imwrite((root / "image_2" / fmt::format("{:06d}.png", i)).string(), TestImage(i, cv::Size(64, 48), CV_8UC3));
    cv::imwrite((root / "image_3" / fmt::format("{:06d}.png", i)).string(), TestImage(i + 5));
  }
  WriteText(root / "times.txt", "0\n0.1\n0.2\n");
  WriteText(root / "calib.txt", "P0: 1 0 0 0 0 1 0 0 0 0 1 0\nP2: 2 0 0 0 0 2 0 0 0 0 1 0\n");

  std::unique_ptr<Sequence> sequence = OpenSequence(root);
  EXPECT_EQ(sequence->layout(), "kitti");
  EXPECT_EQ(sequence->calibration_camera(), "P2");
  ASSERT_TRUE(sequence->calibration_file());
  EXPECT_EQ(*sequence->calibration_file(), root / "calib.txt");
  std::vector<Frame> frames = ReadAll(*sequence);
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[2].image.type(), CV_8UC1);
  EXPECT_EQ(Level(frames[2].image), Level(TestImage(2)));
  EXPECT_DOUBLE_EQ(frames[2].timestamp, 0.2);

  sequence = OpenSequence(root / "image_3");
  EXPECT_EQ(sequence->calibration_camera(), "P3");
  frames = ReadAll(*sequence);
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(Level(frames[0].image), Level(TestImage(5)));

  // times.txt that does not fit names the folder read.
  WriteText(root / "times.txt", "0\n0.1\n");
  const std::string message = ErrorOf([&] { OpenSequence(root); });
  EXPECT_NE(message.find("times.txt: has 2 lines but image_2 holds frame 000002.png"), std::string::npos) << message;
  WriteText(root / "times.txt", "0\n0.1\n0.2\n");

  fs::create_directories(root / "image_0");
  cv::imwrite((root / "image_0" / "000000.png").string(), TestImage(7));
  sequence = OpenSequence(root);
  EXPECT_EQ(sequence->calibration_camera(), "P0");
  EXPECT_EQ(Level(ReadAll(*sequence).front().image), Level(TestImage(7)));
  fs::remove_all(dir);
}

TEST(Sequence, KittiWriterWithoutPoses) {
  const fs::path dir = testing::MakeTempDir("seq_kitti_nogt");
  KittiSequenceWriter writer(dir);
  // A 16-bit frame is stored as 8-bit gray.
  writer.WriteFrame(cv::Mat(48, 64, CV_16UC1, cv::Scalar(256 * 77)), 0.5);
  writer.WriteFrame(TestImage(1), 0.75);
  EXPECT_THROW(writer.WriteFrame(TestImage(2), 1.0, Rigid3d()), std::logic_error);
  EXPECT_EQ(writer.frames_written(), 2u);
  std::unique_ptr<Sequence> sequence = OpenSequence(dir);
  EXPECT_EQ(sequence->layout(), "kitti");
  EXPECT_FALSE(sequence->ground_truth_file());
  EXPECT_FALSE(sequence->calibration_file());
  const std::vector<Frame> frames = ReadAll(*sequence);
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0].image.at<uint8_t>(5, 5), 77);
  EXPECT_EQ(frames[1].timestamp, 0.75);
  fs::remove_all(dir);
}

TEST(Sequence, VideoFile) {
  const fs::path dir = testing::MakeTempDir("seq_video");
  const fs::path file = dir / "clip.avi";
  {
    cv::VideoWriter writer(file.string(), cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 10.0, cv::Size(64, 48), false);
    if (!writer.isOpened()) GTEST_SKIP() << "no MJPG video writer available";
    for (int i = 0; i < 10; ++i) writer.write(TestImage(i));
  }
  std::unique_ptr<Sequence> sequence = OpenSequence(file);
  EXPECT_EQ(sequence->layout(), "video");
  EXPECT_EQ(sequence->size(), 10u);
  EXPECT_EQ(sequence->image_size(), cv::Size(64, 48));
  std::vector<Frame> frames = ReadAll(*sequence);
  ASSERT_EQ(frames.size(), 10u);
  for (int i = 0; i < 10; ++i) {
    EXPECT_EQ(frames[i].index, static_cast<size_t>(i));
    EXPECT_NEAR(frames[i].timestamp, 0.1 * i, 1e-6);
    EXPECT_EQ(frames[i].image.type(), CV_8UC1);
    EXPECT_NEAR(Level(frames[i].image), 20 + 10 * i, 3);  // MJPG is lossy
  }
  // Random access does not disturb streaming.
  sequence->Rewind();
  ASSERT_TRUE(sequence->Next());
  Frame frame;
  ASSERT_TRUE(sequence->Read(7, &frame));
  EXPECT_NEAR(Level(frame.image), 90, 3);
  EXPECT_NEAR(frame.timestamp, 0.7, 1e-6);
  std::optional<Frame> next = sequence->Next();
  ASSERT_TRUE(next);
  EXPECT_EQ(next->index, 1u);
  EXPECT_NEAR(Level(next->image), 30, 3);
  fs::remove_all(dir);
}

TEST(Sequence, SubsampledEvenAndOdd) {
  const fs::path dir = testing::MakeTempDir("seq_sub");
  for (int i = 0; i < 7; ++i) ASSERT_TRUE(cv::imwrite((dir / ("f" + std::to_string(i) + ".png")).string(), TestImage(i)));
  SubsampledSequence even(OpenSequence(dir), 2, 0);
  SubsampledSequence odd(OpenSequence(dir), 2, 1);
  EXPECT_EQ(even.size(), 4u);
  EXPECT_EQ(odd.size(), 3u);
  const std::vector<Frame> even_frames = ReadAll(even);
  const std::vector<Frame> odd_frames = ReadAll(odd);
  ASSERT_EQ(even_frames.size(), 4u);
  ASSERT_EQ(odd_frames.size(), 3u);
  for (size_t i = 0; i < odd_frames.size(); ++i) {
    EXPECT_EQ(odd_frames[i].index, i);
    EXPECT_EQ(odd_frames[i].source_index, 2 * i + 1);
    EXPECT_EQ(Level(odd_frames[i].image), 20 + 10 * static_cast<int>(2 * i + 1));
  }
  Frame frame;
  ASSERT_TRUE(odd.Read(2, &frame));
  EXPECT_EQ(frame.index, 2u);
  EXPECT_EQ(frame.source_index, 5u);
  EXPECT_FALSE(odd.Read(3, &frame));

  // A corrupt odd frame: skipped, the remaining ones keep their positions.
  WriteText(dir / "f3.png", "not a png");
  SubsampledSequence odd_holes(OpenSequence(dir), 2, 1);
  const std::vector<Frame> with_hole = ReadAll(odd_holes);
  ASSERT_EQ(with_hole.size(), 2u);
  EXPECT_EQ(with_hole[1].index, 2u);
  EXPECT_EQ(with_hole[1].source_index, 5u);
  EXPECT_EQ(odd_holes.skipped(), std::vector<std::string>{"f3.png"});

  // Nested: the even positions of the odd frames {1, 3, 5} are source frames 1 and 5.
  SubsampledSequence nested(std::make_unique<SubsampledSequence>(OpenSequence(dir), 2, 1), 2, 0);
  EXPECT_EQ(nested.size(), 2u);
  const std::vector<Frame> nested_frames = ReadAll(nested);
  ASSERT_EQ(nested_frames.size(), 2u);
  EXPECT_EQ(nested_frames[1].index, 1u);
  EXPECT_EQ(nested_frames[1].source_index, 5u);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace retrace
