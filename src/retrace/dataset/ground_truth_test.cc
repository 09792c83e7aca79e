#include "retrace/dataset/ground_truth.h"

#include <cmath>
#include <fstream>

#include <gtest/gtest.h>

#include "retrace/util/error.h"
#include "retrace/util/testing.h"

namespace retrace {
namespace {

namespace fs = std::filesystem;

void WriteText(const fs::path& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
}

Matrix3d RotZ(double deg) { return Eigen::AngleAxisd(deg * M_PI / 180.0, Vector3d::UnitZ()).toRotationMatrix(); }

Rigid3d RandomPose(int seed) {
  std::srand(seed);
  const Eigen::Quaterniond q = Eigen::Quaterniond(Eigen::Vector4d::Random()).normalized();
  return Rigid3d(q.toRotationMatrix(), Vector3d::Random() * 50.0);
}

// Runs `f` and returns the InputError message (fails the test if nothing is thrown).
using retrace::testing::ErrorOf;

TEST(GroundTruth, KittiRealSequence07) {
  RETRACE_REQUIRE_SHARED_DATA(dir, "kitti07");
  const std::vector<TimedPose> poses = ReadKittiPoses(dir / "poses.txt", dir / "times.txt");
  ASSERT_EQ(poses.size(), 160u);
  EXPECT_DOUBLE_EQ(poses[0].timestamp, 0.0);
  EXPECT_NEAR(poses[1].timestamp, 0.1038752, 1e-9);
  // 10 Hz: the 160 frames span ~16.5 s.
  EXPECT_NEAR(poses.back().timestamp, 16.5, 0.3);
  // The first pose is the identity (world = first camera).
  EXPECT_LT((poses[0].world_from_cam.rotation - Matrix3d::Identity()).norm(), 1e-9);
  // Second pose from the file, translation exactly as written.
  EXPECT_DOUBLE_EQ(poses[1].world_from_cam.translation.z(), 0.09154274);
  EXPECT_DOUBLE_EQ(poses[1].world_from_cam.translation.x(), -0.004596714);
  // Re-orthonormalised to machine precision (the file holds 7 digits).
  for (const TimedPose& pose : poses) {
    const Matrix3d& r = pose.world_from_cam.rotation;
    EXPECT_LT((r.transpose() * r - Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
  }
  // The data README says ~90 m; the car drives off along +z of the first camera, then turns left (-x) on a flat road
  // (camera y points down, so height stays within ~1 m).
  const double length = TrajectoryLength(poses);
  EXPECT_GT(length, 80.0);
  EXPECT_LT(length, 100.0);
  EXPECT_GT(poses[20].world_from_cam.translation.z(), 2.0);
  EXPECT_LT(poses.back().world_from_cam.translation.x(), -70.0);
  for (const TimedPose& pose : poses) EXPECT_LT(std::abs(pose.world_from_cam.translation.y()), 1.5);
  // Without times.txt the timestamps are indices.
  const std::vector<TimedPose> indexed = ReadKittiPoses(dir / "poses.txt");
  EXPECT_DOUBLE_EQ(indexed[159].timestamp, 159.0);
}

TEST(GroundTruth, KittiBadLinesNameFileAndLine) {
  const fs::path dir = testing::MakeTempDir("gt_bad");
  const std::string good = "1 0 0 0 0 1 0 0 0 0 1 0\n";
  WriteText(dir / "short.txt", good + good + "1 0 0 0 0 1 0 0 0 0 1\n");
  std::string message = ErrorOf([&] { ReadKittiPoses(dir / "short.txt"); });
  EXPECT_NE(message.find("short.txt"), std::string::npos) << message;
  EXPECT_NE(message.find("line 3"), std::string::npos) << message;
  EXPECT_NE(message.find("expected 12 numbers"), std::string::npos) << message;

  WriteText(dir / "garbage.txt", good + "1 0 0 0 0 1 0 x7 0 0 1 0\n");
  message = ErrorOf([&] { ReadKittiPoses(dir / "garbage.txt"); });
  EXPECT_NE(message.find("line 2"), std::string::npos) << message;
  EXPECT_NE(message.find("'x7' is not a number"), std::string::npos) << message;

  WriteText(dir / "hole.txt", good + "\n" + good);
  message = ErrorOf([&] { ReadKittiPoses(dir / "hole.txt"); });
  EXPECT_NE(message.find("hole.txt: line 2: empty line"), std::string::npos) << message;

  // A scaled matrix is not a rotation with rounding: refused.
  WriteText(dir / "scaled.txt", good + "2 0 0 0 0 2 0 0 0 0 2 0\n");
  message = ErrorOf([&] { ReadKittiPoses(dir / "scaled.txt"); });
  EXPECT_NE(message.find("line 2: the 3x3 part is not a rotation"), std::string::npos) << message;
  // A reflection neither.
  WriteText(dir / "mirror.txt", "-1 0 0 0 0 1 0 0 0 0 1 0\n");
  message = ErrorOf([&] { ReadKittiPoses(dir / "mirror.txt"); });
  EXPECT_NE(message.find("line 1"), std::string::npos) << message;

  // times.txt with the wrong count names times.txt.
  WriteText(dir / "poses.txt", good + good);
  WriteText(dir / "times.txt", "0\n0.1\n0.2\n");
  message = ErrorOf([&] { ReadKittiPoses(dir / "poses.txt", dir / "times.txt"); });
  EXPECT_NE(message.find("times.txt: 3 timestamps but 2 poses"), std::string::npos) << message;

  message = ErrorOf([&] { ReadKittiPoses(dir / "absent.txt"); });
  EXPECT_NE(message.find("absent.txt: no such file"), std::string::npos) << message;
  fs::remove_all(dir);
}

TEST(GroundTruth, KittiRoundTripIsExactAndReorthonormalises) {
  const fs::path dir = testing::MakeTempDir("gt_kitti");
  std::vector<TimedPose> poses;
  for (int i = 0; i < 20; ++i) poses.push_back({0.1 * i + 1e9, RandomPose(i + 1)});
  WriteKittiPoses(dir / "poses.txt", poses, dir / "times.txt");
  const std::vector<TimedPose> back = ReadKittiPoses(dir / "poses.txt", dir / "times.txt");
  ASSERT_EQ(back.size(), poses.size());
  for (size_t i = 0; i < poses.size(); ++i) {
    EXPECT_EQ(back[i].timestamp, poses[i].timestamp);
    EXPECT_EQ(back[i].world_from_cam.translation, poses[i].world_from_cam.translation);
    EXPECT_LT((back[i].world_from_cam.rotation - poses[i].world_from_cam.rotation).cwiseAbs().maxCoeff(), 1e-15);
  }

  // Rounded to 7 digits as in real KITTI files: reading gives an exact rotation within ~1e-7 of the written one.
  const Matrix3d r = RotZ(33.3) * Eigen::AngleAxisd(0.2, Vector3d::UnitX()).toRotationMatrix();
  char line[512];
  std::snprintf(line, sizeof(line), "%.6e %.6e %.6e 1 %.6e %.6e %.6e 2 %.6e %.6e %.6e 3\n", r(0, 0), r(0, 1),
                r(0, 2), r(1, 0), r(1, 1), r(1, 2), r(2, 0), r(2, 1), r(2, 2));
  WriteText(dir / "rounded.txt", line);
  const Matrix3d read = ReadKittiPoses(dir / "rounded.txt")[0].world_from_cam.rotation;
  EXPECT_LT((read.transpose() * read - Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-14);
  EXPECT_LT((read - r).cwiseAbs().maxCoeff(), 2e-6);
  fs::remove_all(dir);
}

TEST(GroundTruth, TumReadWriteAndBadLine) {
  const fs::path dir = testing::MakeTempDir("gt_tum");
  // 90 degrees about z: q = (w, x, y, z) = (cos 45, 0, 0, sin 45).
  const double h = std::sqrt(0.5);
  WriteText(dir / "traj.txt", "# timestamp tx ty tz qx qy qz qw\n\n1305031102.175304 1 2 3 0 0 " +
                                  std::to_string(h) + " " + std::to_string(h) + "\n1305031102.2 4 5 6 0 0 0 1\n");
  const std::vector<TimedPose> poses = ReadTumPoses(dir / "traj.txt");
  ASSERT_EQ(poses.size(), 2u);
  EXPECT_DOUBLE_EQ(poses[0].timestamp, 1305031102.175304);
  EXPECT_EQ(poses[0].world_from_cam.translation, Vector3d(1, 2, 3));
  EXPECT_LT(RotationErrorDeg(poses[0].world_from_cam.rotation, RotZ(90)), 1e-4);
  // x axis of the camera maps to world +y.
  EXPECT_NEAR((poses[0].world_from_cam.rotation * Vector3d::UnitX() - Vector3d::UnitY()).norm(), 0, 1e-6);

  std::vector<TimedPose> random;
  for (int i = 0; i < 10; ++i) random.push_back({i * 0.05, RandomPose(100 + i)});
  WriteTumPoses(dir / "out.txt", random);
  const std::vector<TimedPose> back = ReadTumPoses(dir / "out.txt");
  ASSERT_EQ(back.size(), random.size());
  for (size_t i = 0; i < back.size(); ++i) {
    EXPECT_EQ(back[i].timestamp, random[i].timestamp);
    EXPECT_EQ(back[i].world_from_cam.translation, random[i].world_from_cam.translation);
    // (Compared entry-wise: RotationErrorDeg's acos cannot resolve angles below ~1e-6 deg.)
    EXPECT_LT((back[i].world_from_cam.rotation - random[i].world_from_cam.rotation).cwiseAbs().maxCoeff(), 1e-14);
  }

  WriteText(dir / "bad.txt", "# header\n0 0 0 0 0 0 0 1\n0.1 0 0 0 0 0 0\n");
  std::string message = ErrorOf([&] { ReadTumPoses(dir / "bad.txt"); });
  EXPECT_NE(message.find("bad.txt"), std::string::npos) << message;
  EXPECT_NE(message.find("line 3: expected 8 numbers"), std::string::npos) << message;
  WriteText(dir / "zero.txt", "0 0 0 0 0 0 0 0\n");
  message = ErrorOf([&] { ReadTumPoses(dir / "zero.txt"); });
  EXPECT_NE(message.find("line 1: quaternion norm 0"), std::string::npos) << message;
  fs::remove_all(dir);
}

TEST(GroundTruth, EurocBodyPoses) {
  const fs::path dir = testing::MakeTempDir("gt_euroc");
  WriteText(dir / "data.csv",
            "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z [], "
            "v_RS_R_x [m s^-1]\n"
            "1403715273262142976,0.878612,2.142470,0.947262,0.060514,-0.828459,-0.058956,-0.553641,0.1\n"
            "1403715273312143104,0.9,2.2,1.0,1,0,0,0,0.1\n");
  const std::vector<TimedPose> poses = ReadEurocPoses(dir / "data.csv");
  ASSERT_EQ(poses.size(), 2u);
  EXPECT_NEAR(poses[0].timestamp, 1403715273.262142976, 1e-6);
  EXPECT_NEAR(poses[1].timestamp - poses[0].timestamp, 0.050000128, 1e-6);
  EXPECT_EQ(poses[0].world_from_cam.translation, Vector3d(0.878612, 2.142470, 0.947262));
  const Eigen::Quaterniond q(0.060514, -0.828459, -0.058956, -0.553641);
  EXPECT_LT(RotationErrorDeg(poses[0].world_from_cam.rotation, q.normalized().toRotationMatrix()), 1e-9);
  EXPECT_LT((poses[1].world_from_cam.rotation - Matrix3d::Identity()).norm(), 1e-15);

  WriteText(dir / "bad.csv", "#timestamp,x\n1403715273262142976,1,2,3,1,0,0\n");
  const std::string message = ErrorOf([&] { ReadEurocPoses(dir / "bad.csv"); });
  EXPECT_NE(message.find("bad.csv"), std::string::npos) << message;
  EXPECT_NE(message.find("line 2"), std::string::npos) << message;
  fs::remove_all(dir);
}

TEST(GroundTruth, InterpolationSlerpAndLinear) {
  std::vector<TimedPose> poses = {{10.0, Rigid3d(RotZ(0), Vector3d(0, 0, 0))},
                                  {11.0, Rigid3d(RotZ(90), Vector3d(2, 0, 0))},
                                  {13.0, Rigid3d(RotZ(90), Vector3d(2, 4, 0))}};
  std::optional<Rigid3d> p = InterpolatePose(poses, 10.25);
  ASSERT_TRUE(p);
  EXPECT_LT(RotationErrorDeg(p->rotation, RotZ(22.5)), 1e-9);
  EXPECT_LT((p->translation - Vector3d(0.5, 0, 0)).norm(), 1e-12);
  p = InterpolatePose(poses, 12.5);
  ASSERT_TRUE(p);
  EXPECT_LT(RotationErrorDeg(p->rotation, RotZ(90)), 1e-9);
  EXPECT_LT((p->translation - Vector3d(2, 3, 0)).norm(), 1e-12);
  // Exactly on the samples.
  EXPECT_LT((InterpolatePose(poses, 11.0)->translation - Vector3d(2, 0, 0)).norm(), 1e-12);
  EXPECT_LT((InterpolatePose(poses, 13.0)->translation - Vector3d(2, 4, 0)).norm(), 1e-12);
  EXPECT_LT((InterpolatePose(poses, 10.0)->translation).norm(), 1e-12);
  // Outside the time span, or empty.
  EXPECT_FALSE(InterpolatePose(poses, 9.999));
  EXPECT_FALSE(InterpolatePose(poses, 13.001));
  EXPECT_FALSE(InterpolatePose({}, 0.0));
  // Slerp takes the short way: 170 deg to -170 deg about z passes through 180, not 0.
  const std::vector<TimedPose> wrap = {{0.0, Rigid3d(RotZ(170), Vector3d::Zero())},
                                       {1.0, Rigid3d(RotZ(-170), Vector3d::Zero())}};
  EXPECT_LT(RotationErrorDeg(InterpolatePose(wrap, 0.5)->rotation, RotZ(180)), 1e-9);

  EXPECT_DOUBLE_EQ(TrajectoryLength(poses), 6.0);
  EXPECT_DOUBLE_EQ(TrajectoryLength({}), 0.0);
}

}  // namespace
}  // namespace retrace
