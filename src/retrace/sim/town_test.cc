#include "retrace/sim/town.h"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "retrace/sim/simulator.h"
#include "retrace/util/error.h"
#include "retrace/util/testing.h"

namespace retrace {
namespace {

TEST(TownTest, StreetsHaveJunctionsAndTheRouteTurns) {
  Scene scene;
  TownOptions options;
  options.blocks_x = 3;
  options.blocks_y = 2;
  const TownLayout layout = BuildTown(options, &scene);
  ASSERT_EQ(layout.street_x.size(), 4u);
  ASSERT_EQ(layout.street_y.size(), 3u);
  for (size_t i = 1; i < layout.street_x.size(); ++i) {
    const double block = layout.street_x[i] - layout.street_x[i - 1] - options.road_width - 2 * options.sidewalk_width;
    EXPECT_GE(block, options.block_size_min - 1e-9);
    EXPECT_LE(block, options.block_size_max + 1e-9);
  }
  EXPECT_GT(scene.num_static_triangles(), 10000u);
  EXPECT_EQ(scene.num_moving_objects(), static_cast<size_t>(options.num_pedestrians + options.num_moving_cars));
  // A random route of 8 streets turns at least once and never makes a U-turn.
  const std::vector<Vector2d> route = RandomRouteJunctions(layout, 8, 5);
  ASSERT_EQ(route.size(), 9u);
  int turns = 0;
  for (size_t k = 1; k + 1 < route.size(); ++k) {
    const Vector2d a = (route[k] - route[k - 1]).normalized(), b = (route[k + 1] - route[k]).normalized();
    EXPECT_GT(a.dot(b), -0.5);
    turns += a.dot(b) < 0.5;
  }
  EXPECT_GE(turns, 1);
  // The right lane lies right of the direction of travel.
  const std::vector<Vector2d> lane = OffsetPolyline({{0, 0}, {10, 0}}, 2.0);
  EXPECT_NEAR(lane[0].y(), -2.0, 1e-12);
}

TEST(TownTest, OnStreetsIsTrueOnCarriagewaysAndSidewalksOnly) {
  TownLayout layout;
  layout.street_x = {0.0, 50.0};
  layout.street_y = {0.0, 40.0};
  const double half = layout.road_width / 2 + layout.sidewalk_width;  // 6.5 m
  EXPECT_TRUE(layout.OnStreets({25.0, 0.0}));           // on a west-east street
  EXPECT_TRUE(layout.OnStreets({50.0, 20.0}));          // on a south-north street
  EXPECT_TRUE(layout.OnStreets({25.0, half - 0.01}));   // its sidewalk
  EXPECT_FALSE(layout.OnStreets({25.0, half + 0.01}));  // the block behind it
  EXPECT_FALSE(layout.OnStreets({25.0, 20.0}));         // inside the block
  EXPECT_FALSE(layout.OnStreets({-half - 0.01, 0.0}));  // out of the town
  EXPECT_FALSE(TownLayout().OnStreets({0.0, 0.0}));     // no streets
}

TEST(TownTest, ViewsAreRichInCornersForTracking) {
  Scenario s;
  s.town.blocks_x = 2;
  s.town.blocks_y = 2;
  s.num_frames = 30;
  Simulator sim(s);
  SimFrame frame;
  int frames = 0;
  double min_corners = 1e9;
  while (sim.NextFrame(&frame)) {
    if (frames++ % 10 != 0) continue;
    std::vector<cv::Point2f> corners;
    cv::goodFeaturesToTrack(frame.image, corners, 1000, 0.01, 5.0, cv::noArray(), 3, true);  // Harris
    min_corners = std::min(min_corners, static_cast<double>(corners.size()));
  }
  std::cout << "fewest Harris corners in a 320x240 view: " << min_corners << "\n";
  // For comparison, real KITTI seq. 07 frames resized to 320x97 give 77-143 corners with the same settings (about
  // 190-350 for this image area); the simulated views give about 130-270.
  EXPECT_GT(min_corners, 120.0);
}

TEST(TownTest, UserPhotosTextureTheFacades) {
  const std::filesystem::path dir = testing::MakeTempDir("sim_photos");
  cv::Mat photo(120, 160, CV_8UC3);
  cv::randu(photo, cv::Scalar::all(0), cv::Scalar::all(255));
  cv::imwrite((dir / "a.png").string(), photo);
  cv::imwrite((dir / "b.jpg").string(), 255 - photo);
  TownOptions options;
  options.blocks_x = 1;
  options.blocks_y = 1;
  options.photo_folder = dir.string();
  Scene scene;
  BuildTown(options, &scene);
  // The two photos replace the 8 procedural facades (textures: 2 photos + 4 shop fronts + the rest).
  Scene procedural;
  options.photo_folder.clear();
  BuildTown(options, &procedural);
  EXPECT_EQ(procedural.textures().size() - scene.textures().size(), 6u);
  bool found = false;
  for (const Texture& t : scene.textures()) found |= t.width() == 160 && t.height() == 120;
  EXPECT_TRUE(found);
  // An empty or missing folder is an input error naming it.
  const std::filesystem::path empty = testing::MakeTempDir("sim_photos_empty");
  options.photo_folder = empty.string();
  Scene s2;
  EXPECT_THROW(BuildTown(options, &s2), InputError);
  options.photo_folder = (empty / "missing").string();
  Scene s3;
  EXPECT_THROW(BuildTown(options, &s3), InputError);
}

}  // namespace
}  // namespace retrace
