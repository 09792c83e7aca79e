#include "retrace/sim/renderer.h"

#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "retrace/camera/equirectangular_camera.h"
#include "retrace/camera/perspective_camera.h"
#include "retrace/camera/unified_camera.h"
#include "retrace/sim/scenario.h"
#include "retrace/sim/simulator.h"

namespace retrace {
namespace {

// Intensity-weighted centroid of the pixels within `radius` of `around` (background must be black).
bool Centroid(const cv::Mat& image, const Vector2d& around, int radius, Vector2d* centroid, double* mass) {
  double sx = 0, sy = 0, sw = 0;
  const int cx = static_cast<int>(std::round(around.x())), cy = static_cast<int>(std::round(around.y()));
  for (int y = cy - radius; y <= cy + radius; ++y) {
    for (int x = cx - radius; x <= cx + radius; ++x) {
      if (x < 0 || y < 0 || x >= image.cols || y >= image.rows) continue;
      const double w = image.at<uint8_t>(y, x);
      sx += w * x;
      sy += w * y;
      sw += w;
    }
  }
  *mass = sw;
  if (sw <= 0) return false;
  *centroid = Vector2d(sx / sw, sy / sw);
  return true;
}

Rigid3d SomeTownFromCam() {
  const Matrix3d r = (Eigen::AngleAxisd(0.7, Vector3d::UnitZ()) * Eigen::AngleAxisd(-1.9, Vector3d::UnitX()) *
                      Eigen::AngleAxisd(0.1, Vector3d::UnitY()))
                         .toRotationMatrix();
  return Rigid3d(r, Vector3d(12.0, -4.0, 1.6));
}

struct MarkerScene {
  std::unique_ptr<Scene> scene;
  std::vector<Vector3d> points;  // town frame
};

// Self-luminous discs facing the camera centre at the given camera-frame points, with an angular radius of
// `radius_rad`, on a black sky.
MarkerScene MakeMarkers(const Rigid3d& town_from_cam, const std::vector<Vector3d>& points_in_cam,
                        double radius_rad) {
  MarkerScene m;
  m.scene = std::make_unique<Scene>();
  Material glow;
  glow.emissive = true;
  glow.color = Vector3f::Constant(0.8f);
  const int material = m.scene->AddMaterial(glow);
  Mesh mesh;
  for (const Vector3d& p : points_in_cam) {
    const Vector3d x = town_from_cam * p;
    const Vector3d towards_camera = town_from_cam.translation - x;
    mesh.AddDisc(x.cast<float>(), towards_camera.cast<float>(), static_cast<float>(radius_rad * p.norm()), 48,
                 material);
    m.points.push_back(x);
  }
  m.scene->AddStaticMesh(mesh);
  m.scene->set_sky(SkyType::kUniform, Vector3f::Zero());
  m.scene->Commit();
  return m;
}

void ExpectMarkersWhereProjected(const CameraModel& camera, const Rigid3d& town_from_cam, const MarkerScene& m,
                                 int window, double* max_error) {
  RenderOptions options;
  options.antialiasing = 4;
  Renderer renderer(camera, options);
  SensorOptions sensor;
  sensor.noise_sigma = 0.0;
  const cv::Mat image = renderer.Render(*m.scene, town_from_cam, Lighting(), sensor, 0);
  ASSERT_EQ(image.type(), CV_8UC1);
  const Rigid3d cam_from_town = town_from_cam.Inverse();
  *max_error = 0.0;
  for (size_t i = 0; i < m.points.size(); ++i) {
    Vector2d expected;
    ASSERT_TRUE(camera.Project(cam_from_town * m.points[i], &expected));
    ASSERT_TRUE(camera.InImage(expected, window)) << expected.transpose();
    Vector2d centroid;
    double mass = 0.0;
    ASSERT_TRUE(Centroid(image, expected, window, &centroid, &mass)) << "marker " << i << " not drawn";
    EXPECT_GT(mass, 5 * 200.0) << "marker " << i << " too faint";
    const double error = (centroid - expected).norm();
    EXPECT_LT(error, 0.5) << "marker " << i << " expected at " << expected.transpose() << " drawn at "
                          << centroid.transpose();
    *max_error = std::max(*max_error, error);
  }
}

TEST(RendererTest, MarkersAppearWhereTheDistortedPerspectiveModelProjects) {
  const LensDistortion distortion{-0.28, 0.09, 0.0, 0.0012, -0.0008};
  const PerspectiveCamera camera(320, 240, 210.0, 205.0, 161.3, 118.7, 0.0, distortion);
  const Rigid3d town_from_cam = SomeTownFromCam();
  // Markers on a grid of pixels out to the image corners, at various depths.
  std::vector<Vector3d> points;
  int k = 0;
  for (double v = 14; v < 240; v += 35) {
    for (double u = 14; u < 320; u += 36, ++k) {
      Vector3d bearing;
      ASSERT_TRUE(camera.Unproject(Vector2d(u, v), &bearing));
      points.push_back(bearing / bearing.z() * (4.0 + (k % 5) * 3.0));
    }
  }
  const MarkerScene m = MakeMarkers(town_from_cam, points, 3.0 / 210.0);
  double max_error = 0.0;
  ExpectMarkersWhereProjected(camera, town_from_cam, m, 8, &max_error);
  std::cout << "perspective+distortion: " << points.size() << " markers, max centroid error " << max_error
            << " px\n";
  // The test has teeth: the distortion moves corner markers by many pixels, so ignoring it would fail.
  const PerspectiveCamera pinhole(320, 240, 210.0, 205.0, 161.3, 118.7);
  double max_shift = 0.0;
  for (const Vector3d& x : m.points) {
    Vector2d a, b;
    camera.Project(town_from_cam.Inverse() * x, &a);
    pinhole.Project(town_from_cam.Inverse() * x, &b);
    max_shift = std::max(max_shift, (a - b).norm());
  }
  EXPECT_GT(max_shift, 10.0);
}

TEST(RendererTest, MarkersAppearWhereThePanoramicModelProjects) {
  const EquirectangularCamera camera(480, 240);
  const Rigid3d town_from_cam = SomeTownFromCam();
  std::vector<Vector3d> points;
  int k = 0;
  for (double lat = -60; lat <= 60; lat += 20) {
    for (double lon = -165; lon <= 165; lon += 30, ++k) {
      const double la = lat * M_PI / 180, lo = lon * M_PI / 180;
      // Longitude around the camera y axis from +z towards +x, latitude towards +y (down).
      const Vector3d bearing(std::cos(la) * std::sin(lo), std::sin(la), std::cos(la) * std::cos(lo));
      points.push_back(bearing * (3.0 + (k % 4) * 4.0));
    }
  }
  const MarkerScene m = MakeMarkers(town_from_cam, points, 2.5 / camera.FocalLength());
  double max_error = 0.0;
  ExpectMarkersWhereProjected(camera, town_from_cam, m, 7, &max_error);
  std::cout << "equirectangular: " << points.size() << " markers, max centroid error " << max_error << " px\n";
}

TEST(RendererTest, MarkersAppearWhereTheFisheyeUnifiedModelProjects) {
  // A 190 degree fisheye (Mei's unified model with xi = 1.2) with distortion: rays behind the image plane too.
  const UnifiedCamera camera(320, 320, 1.2, 150.0, 150.0, 159.5, 160.2, 0.0, LensDistortion{-0.05, 0.01, 0.0, 0.0, 0.0});
  const Rigid3d town_from_cam = SomeTownFromCam();
  std::vector<Vector3d> points;
  int k = 0;
  for (double v = 20; v < 310; v += 32) {
    for (double u = 20; u < 310; u += 32, ++k) {
      if ((Vector2d(u, v) - Vector2d(159.5, 160.2)).norm() > 150.0) continue;
      Vector3d bearing;
      if (!camera.Unproject(Vector2d(u, v), &bearing)) continue;
      points.push_back(bearing * (3.0 + (k % 4) * 3.0));
    }
  }
  ASSERT_GT(points.size(), 40u);
  const MarkerScene m = MakeMarkers(town_from_cam, points, 2.5 / camera.FocalLength());
  double max_error = 0.0;
  ExpectMarkersWhereProjected(camera, town_from_cam, m, 8, &max_error);
  std::cout << "unified fisheye: " << points.size() << " markers, max centroid error " << max_error << " px\n";
}

TEST(RendererTest, MovingOccluderCrossesInFrontOfTheCamera) {
  // A self-luminous 1 m cube walks along y from -10 to +10 at 5 m/s, 10 m in front of a camera looking along +x.
  Scene scene;
  Material glow;
  glow.emissive = true;
  glow.color = Vector3f::Constant(0.8f);
  Mesh cube;
  cube.AddBox(Vector3f(-0.5f, -0.5f, 1.0f), Vector3f(0.5f, 0.5f, 2.0f), 1.0f, scene.AddMaterial(glow));
  ScriptedPath path;
  path.points = {{10.0, -10.0}, {10.0, 10.0}};
  path.speed = 5.0;
  path.loop = false;
  scene.AddMovingObject(cube, path);
  scene.set_sky(SkyType::kUniform, Vector3f::Zero());
  // Camera at height 1.5 looking east (+x): x_cam = -y_town (right = south), y_cam = -z_town.
  Matrix3d r;
  r << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  const Rigid3d town_from_cam(r, Vector3d(0, 0, 1.5));
  const PerspectiveCamera camera(160, 120, 100, 100, 79.5, 59.5);
  RenderOptions options;
  options.antialiasing = 4;
  Renderer renderer(camera, options);
  SensorOptions sensor;
  sensor.noise_sigma = 0.0;
  for (double time : {1.0, 2.0, 3.0}) {  // y = -5, 0, +5: right of the centre, centre, left
    scene.SetTime(time);
    const cv::Mat image = renderer.Render(scene, town_from_cam, Lighting(), sensor, 0);
    const cv::Moments moments = cv::moments(image);
    ASSERT_GT(moments.m00, 0.0) << "occluder not visible at t=" << time;
    Vector2d expected;
    ASSERT_TRUE(camera.Project(town_from_cam.Inverse() * Vector3d(10.0, -10.0 + 5.0 * time, 1.5), &expected));
    // The centroid of a cube seen slightly from the side is not exactly its centre's projection: 1.5 px.
    EXPECT_NEAR(moments.m10 / moments.m00, expected.x(), 1.5) << "t=" << time;
    EXPECT_NEAR(moments.m01 / moments.m00, expected.y(), 1.5) << "t=" << time;
  }
  // Back and forth when not looping: at t = 6 s it has reached +10 and returned 10 m to y = 0.
  EXPECT_NEAR(path.PoseAt(6.0).translation.y(), 0.0, 1e-9);
  EXPECT_NEAR(path.PoseAt(6.0).rotation(1, 0), -1.0, 1e-9);  // now walking towards -y
}

// Edge anti-aliasing against shimmer: a bright square, tilted by 10 degrees, on a black sky; the camera slides
// sideways in steps of 0.1 px. With point sampling an edge pixel flips from black to full brightness within one step
// (the shimmer of a moving camera); with the quincunx edge samples no pixel changes by much more than half the
// contrast per step, and the square's centroid follows the motion.
TEST(RendererTest, EdgeAntialiasingMovesEdgesSmoothly) {
  Scene scene;
  Material glow;
  glow.emissive = true;
  glow.color = Vector3f::Constant(0.8f);
  const int material = scene.AddMaterial(glow);
  Mesh mesh;
  const Eigen::Matrix3f tilt = Eigen::AngleAxisf(0.1745f, Vector3f::UnitZ()).toRotationMatrix();
  auto corner = [&](float x, float y) { return Vector3f(tilt * Vector3f(x, y, 0.0f) + Vector3f(0.0f, 0.0f, 10.0f)); };
  mesh.AddQuad(corner(-1.5f, -1.5f), corner(1.5f, -1.5f), corner(1.5f, 1.5f), corner(-1.5f, 1.5f), Vector2f(0, 0),
               Vector2f(1, 0), Vector2f(1, 1), Vector2f(0, 1), material);
  scene.AddStaticMesh(mesh);
  scene.set_sky(SkyType::kUniform, Vector3f::Zero());
  scene.Commit();
  const PerspectiveCamera camera(160, 120, 100, 100, 79.5, 59.5);  // 0.01 m at 10 m = 0.1 px
  SensorOptions sensor;
  sensor.noise_sigma = 0.0;
  struct Motion {
    double max_jump = 0.0;            // largest change of one pixel between consecutive steps, grey levels
    double max_centroid_error = 0.0;  // px
    double contrast = 0.0;
  };
  auto slide = [&](int antialiasing) {
    RenderOptions options;
    options.antialiasing = antialiasing;
    const Renderer renderer(camera, options);
    Motion motion;
    cv::Mat previous;
    double x0 = 0.0;
    for (int k = 0; k <= 10; ++k) {
      const Rigid3d town_from_cam(Matrix3d::Identity(), Vector3d(0.01 * k, 0.0, 0.0));
      cv::Mat image;
      renderer.Render(scene, town_from_cam, Lighting(), sensor, 0).convertTo(image, CV_64F);
      const cv::Moments m = cv::moments(image);
      const double x = m.m10 / m.m00;
      if (k == 0) {
        x0 = x;
        cv::minMaxLoc(image, nullptr, &motion.contrast);
      } else {
        double jump = 0.0;
        cv::minMaxLoc(cv::abs(image - previous), nullptr, &jump);
        motion.max_jump = std::max(motion.max_jump, jump);
      }
      motion.max_centroid_error = std::max(motion.max_centroid_error, std::abs(x - (x0 - 0.1 * k)));
      previous = image;
    }
    return motion;
  };
  const Motion point = slide(1), smooth = slide(2);
  std::cout << "0.1 px steps: largest pixel change " << point.max_jump << " (point sampled) vs " << smooth.max_jump
            << " (edge anti-aliasing) of " << smooth.contrast << " grey levels; centroid error "
            << point.max_centroid_error << " vs " << smooth.max_centroid_error << " px\n";
  ASSERT_GT(smooth.contrast, 150.0);
  EXPECT_GT(point.max_jump, 0.9 * point.contrast);  // the test can see shimmer
  EXPECT_LT(smooth.max_jump, 0.55 * smooth.contrast);
  EXPECT_LT(smooth.max_centroid_error, 0.05);  // the square follows the motion
}

Scenario SmallTown() {
  Scenario s;
  s.town.blocks_x = 2;
  s.town.blocks_y = 2;
  s.camera.width = 160;
  s.camera.height = 120;
  s.route.segments = 3;
  s.num_frames = 3;
  return s;
}

TEST(RendererTest, SameScenarioAndSeedGiveByteIdenticalImages) {
  Scenario a = SmallTown();
  a.sensor.noise_sigma = 2.0;
  Scenario b = a;
  b.render.num_threads = 1;  // thread count must not matter either
  Simulator sim_a(a), sim_b(b);
  SimFrame fa, fb;
  int frames = 0;
  while (sim_a.NextFrame(&fa)) {
    ASSERT_TRUE(sim_b.NextFrame(&fb));
    ASSERT_EQ(fa.image.size(), fb.image.size());
    EXPECT_EQ(cv::norm(fa.image, fb.image, cv::NORM_L1), 0.0) << "frame " << frames;
    ++frames;
  }
  EXPECT_EQ(frames, 3);
  // A different seed gives a different town.
  Scenario c = a;
  c.seed = c.town.seed = 99;
  Simulator sim_c(c);
  SimFrame fc;
  ASSERT_TRUE(sim_c.NextFrame(&fc));
  Simulator sim_a2(a);
  ASSERT_TRUE(sim_a2.NextFrame(&fa));
  EXPECT_GT(cv::norm(fa.image, fc.image, cv::NORM_L1), 0.0);
}

TEST(RendererTest, TexturedTownHasContrastAndShadows) {
  Scenario s = SmallTown();
  s.sensor.noise_sigma = 0.0;
  Simulator sim(s);
  SimFrame f;
  ASSERT_TRUE(sim.NextFrame(&f));
  cv::Scalar mean, stddev;
  cv::meanStdDev(f.image, mean, stddev);
  EXPECT_GT(stddev[0], 25.0);
  EXPECT_GT(mean[0], 60.0);
  EXPECT_LT(mean[0], 200.0);
  // Without the sun nothing gets brighter, and the sunlit part (a good share of the view) gets darker.
  Scenario dark = s;
  dark.lighting.sun_elevation_deg = -5.0;
  Simulator sim_dark(dark);
  SimFrame g;
  ASSERT_TRUE(sim_dark.NextFrame(&g));
  cv::Mat brighter, darker, lift;
  cv::subtract(g.image, f.image, lift);
  cv::compare(lift, 3, brighter, cv::CMP_GT);  // (edge pixels may be anti-aliased differently by 1-2 levels)
  cv::Mat diff;
  cv::subtract(f.image, g.image, diff);
  cv::compare(diff, 20, darker, cv::CMP_GT);
  EXPECT_LE(cv::countNonZero(brighter), static_cast<int>(f.image.total() / 1000));
  EXPECT_GT(cv::countNonZero(darker), static_cast<int>(0.05 * f.image.total()));
}

// Anti-aliasing against ground truth: the filtered render must be close to the scene integrated over each pixel
// (an 8x8 supersampled render, box-filtered), much closer than plain point sampling, which aliases and would
// shimmer as the camera moves.
TEST(RendererTest, FilteredRenderApproximatesThePixelIntegral) {
  Scenario s = SmallTown();
  s.town.num_pedestrians = 0;
  s.town.num_moving_cars = 0;
  s.num_frames = 20;
  Simulator sim(s);
  SimFrame frame;
  for (int k = 0; k < 15; ++k) ASSERT_TRUE(sim.NextFrame(&frame));  // a view along a street
  const std::unique_ptr<CameraModel> camera = s.camera.MakeCamera();
  SensorOptions sensor;
  sensor.noise_sigma = 0.0;
  auto render = [&](const CameraModel& cam, bool filter, int antialiasing) {
    RenderOptions options;
    options.filter_textures = filter;
    options.antialiasing = antialiasing;
    cv::Mat image;
    Renderer(cam, options).Render(sim.scene(), frame.town_from_cam, s.lighting, sensor, 0).convertTo(image, CV_32F);
    return image;
  };
  const std::unique_ptr<CameraModel> fine = camera->Scaled(8.0);
  cv::Mat reference;
  cv::resize(render(*fine, false, 1), reference, camera->width() > 0 ? cv::Size(camera->width(), camera->height())
                                                                     : cv::Size(),
             0, 0, cv::INTER_AREA);
  const double filtered = cv::norm(render(*camera, true, 2), reference, cv::NORM_L1) / reference.total();
  const double point_sampled = cv::norm(render(*camera, false, 1), reference, cv::NORM_L1) / reference.total();
  const double no_edge_samples = cv::norm(render(*camera, true, 1), reference, cv::NORM_L1) / reference.total();
  std::cout << "mean |render - pixel integral|: filtered " << filtered << ", point sampled " << point_sampled
            << ", filtered textures without edge samples " << no_edge_samples << " grey levels\n";
  EXPECT_LT(filtered, 0.6 * point_sampled);
  EXPECT_LT(filtered, 6.0);
  EXPECT_LT(filtered, 0.92 * no_edge_samples);  // the edge samples do their share
}

}  // namespace
}  // namespace retrace
