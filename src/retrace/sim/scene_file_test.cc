#include "retrace/sim/scene_file.h"

#include <fstream>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "retrace/sim/simulator.h"
#include "retrace/util/error.h"
#include "retrace/util/testing.h"

namespace retrace {
namespace {

// An OBJ (Y up) with a grey ground and a checkerboard-textured wall 25 m ahead of a route along +X.
std::filesystem::path WriteObjScene(const std::filesystem::path& dir) {
  cv::Mat checker(256, 256, CV_8UC3);
  for (int y = 0; y < 256; ++y) {
    for (int x = 0; x < 256; ++x) {
      checker.at<cv::Vec3b>(y, x) = ((x / 32 + y / 32) % 2) ? cv::Vec3b(230, 230, 230) : cv::Vec3b(20, 20, 20);
    }
  }
  cv::imwrite((dir / "checker.png").string(), checker);
  std::ofstream mtl(dir / "scene.mtl");
  mtl << "newmtl ground\nKd 0.4 0.4 0.4\n\nnewmtl wall\nKd 1 1 1\nmap_Kd checker.png\n";
  std::ofstream obj(dir / "scene.obj");
  obj << "mtllib scene.mtl\n"
      << "v -50 0 50\nv 50 0 50\nv 50 0 -50\nv -50 0 -50\n"       // ground (y = 0)
      << "v 25 0 5\nv 25 0 -5\nv 25 8 -5\nv 25 8 5\n"             // wall at x = 25, 10 m wide, 8 m high
      << "vt 0 0\nvt 4 0\nvt 4 3.2\nvt 0 3.2\n"
      << "usemtl ground\nf 1 2 3\nf 1 3 4\n"
      << "usemtl wall\nf 5/1 6/2 7/3\nf 5/1 7/3 8/4\n";
  return dir / "scene.obj";
}

TEST(SceneFileTest, RendersAUserObjSceneWithItsTexture) {
  const std::filesystem::path dir = testing::MakeTempDir("sim_scene_file");
  Scenario s;
  s.scene_file = WriteObjScene(dir).string();
  s.route.type = "waypoints";
  s.route.waypoints = {{0, 0}, {20, 0}};
  s.camera.width = 160;
  s.camera.height = 120;
  s.vehicle.camera_tilt_deg = 0.0;
  s.sensor.noise_sigma = 0.0;
  s.num_frames = 1;
  ASSERT_EQ(s.Validate(), "");
  Simulator sim(s);
  SimFrame f;
  ASSERT_TRUE(sim.NextFrame(&f));
  // The wall fills the middle of the view with the checkerboard: strong contrast, both dark and bright squares.
  const cv::Mat centre = f.image(cv::Rect(60, 40, 40, 40));
  double lo, hi;
  cv::minMaxLoc(centre, &lo, &hi);
  EXPECT_GT(hi - lo, 100.0);
  // Above the 8 m wall at 25 m (16 degrees up) the sky is bright and smooth; the ground below is uniform grey.
  cv::Scalar mean, stddev;
  cv::meanStdDev(f.image(cv::Rect(0, 0, 160, 8)), mean, stddev);
  EXPECT_GT(mean[0], 120.0);
  EXPECT_LT(stddev[0], 12.0);
  cv::meanStdDev(f.image(cv::Rect(0, 110, 160, 10)), mean, stddev);
  EXPECT_LT(stddev[0], 6.0);
}

TEST(SceneFileTest, BadScenesAreInputErrors) {
  const std::filesystem::path dir = testing::MakeTempDir("sim_scene_bad");
  Scene scene;
  EXPECT_THROW(LoadSceneFile(dir / "missing.obj", SceneFileOptions(), &scene), InputError);
  std::ofstream(dir / "garbage.obj") << "this is not geometry\n";
  EXPECT_THROW(LoadSceneFile(dir / "garbage.obj", SceneFileOptions(), &scene), InputError);
  Scenario s;
  s.scene_file = (dir / "x.obj").string();
  EXPECT_NE(s.Validate(), "");  // a scene file needs waypoints
}

}  // namespace
}  // namespace retrace
