// Teach on drives with a stretch that cannot support geometry (issue 18): an empty plane of fine ground texture, and
// a plane of identical paving tiles. A street between two textured walls, the walls missing over 50 m in the middle:
// there the camera sees the ground plane alone. Teach must write no arc across that stretch whose motion is wrong,
// leave the map disconnected there and report why, and still write the arcs of the street before and after.
//
// The drives are rendered here by ray casting (no simulator): the ground and the walls are planes with analytic
// textures, sampled 2x2 per pixel.

#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include "retrace/camera/perspective_camera.h"
#include "retrace/feature/synthetic_texture.h"
#include "retrace/teach/planar_degeneracy.h"
#include "retrace/teach/teacher.h"

namespace retrace {
namespace {

constexpr int kWidth = 320, kHeight = 240;
constexpr double kCameraHeight = 1.5;        // metres above the ground
constexpr double kTiltDeg = 5.0;             // downwards
constexpr double kWallDistance = 4.0;        // metres left and right of the camera's path
constexpr double kWallTop = -6.0;            // world y (down) of the walls' top edge: 7.5 m high walls
constexpr double kStep = 0.8;                // metres per frame (8 m/s at 10 frames/s, as the simulated town)
constexpr double kOpenBegin = 20.0, kOpenEnd = 70.0;  // no walls for z in (kOpenBegin, kOpenEnd)
constexpr int kFrames = 126;                 // z from 0 to 100 m

enum class Ground { kFineNoise, kTiles };

// Grey level of a texture image at (u, v) texels, bilinear, wrapped around.
double SampleWrapped(const cv::Mat& texture, double u, double v) {
  const int w = texture.cols, h = texture.rows;
  const double fu = std::floor(u), fv = std::floor(v);
  const double au = u - fu, av = v - fv;
  const auto at = [&](long x, long y) {
    const int row = static_cast<int>(((y % h) + h) % h), column = static_cast<int>(((x % w) + w) % w);
    return static_cast<double>(texture.at<float>(row, column));
  };
  const long x = static_cast<long>(fu), y = static_cast<long>(fv);
  return (1 - av) * ((1 - au) * at(x, y) + au * at(x + 1, y)) + av * ((1 - au) * at(x, y + 1) + au * at(x + 1, y + 1));
}

class Street {
 public:
  explicit Street(Ground ground) : ground_(ground) {
    // 41 m x 10 m of wall texture per walled stretch (2 cm texels), another for each: nothing repeats along them.
    for (const uint64_t seed : {3, 4}) {
      SyntheticTextureOptions wall;
      wall.width = 2048;
      wall.height = 512;
      wall.num_shapes = 2500;
      wall.seed = seed;
      wall_textures_.push_back(SyntheticTexture(wall).Render(2048, 512));
    }
    // Fine noise: independent grey levels per centimetre, blurred over 1 cm, low contrast (asphalt seen from 1.5 m).
    noise_texture_ = cv::Mat(2048, 2048, CV_32F);
    std::mt19937 random(5);
    std::normal_distribution<float> grey(0.0f, 14.0f);
    for (int y = 0; y < noise_texture_.rows; ++y) {
      for (int x = 0; x < noise_texture_.cols; ++x) noise_texture_.at<float>(y, x) = 110.0f + grey(random);
    }
    cv::GaussianBlur(noise_texture_, noise_texture_, cv::Size(0, 0), 1.0, 1.0, cv::BORDER_REFLECT);
  }

  const PerspectiveCamera& camera() const { return camera_; }

  // Camera pose of frame k: on the path x = 0, z = kStep k, tilted down.
  Rigid3d WorldFromCamera(int k) const {
    const double tilt = kTiltDeg * M_PI / 180.0;
    Rigid3d pose;
    pose.rotation << 1, 0, 0, 0, std::cos(tilt), std::sin(tilt), 0, -std::sin(tilt), std::cos(tilt);
    pose.translation = Vector3d(0, 0, kStep * k);
    return pose;
  }

  Frame Render(int k) const {
    const Rigid3d pose = WorldFromCamera(k);
    constexpr int kSupersampling = 2;
    cv::Mat fine(kHeight * kSupersampling, kWidth * kSupersampling, CV_32F);
    for (int y = 0; y < fine.rows; ++y) {
      for (int x = 0; x < fine.cols; ++x) {
        const Vector2d pixel((x + 0.5) / kSupersampling - 0.5, (y + 0.5) / kSupersampling - 0.5);
        Vector3d ray;
        camera_.Unproject(pixel, &ray);
        fine.at<float>(y, x) = static_cast<float>(Shade(pose.translation, pose.rotation * ray));
      }
    }
    cv::Mat small, image;
    cv::resize(fine, small, cv::Size(kWidth, kHeight), 0, 0, cv::INTER_AREA);
    small.convertTo(image, CV_8U);
    Frame frame;
    frame.index = static_cast<size_t>(k);
    frame.source_index = static_cast<size_t>(k);
    frame.name = std::to_string(k);
    frame.timestamp = 0.1 * k;
    frame.image = image;
    return frame;
  }

 private:
  static bool Walled(double z) { return z <= kOpenBegin || z >= kOpenEnd; }

  // The ground of the walled stretches is the fine noise; the open stretch has the ground under test.
  double GroundGrey(double x, double z) const {
    if (ground_ == Ground::kFineNoise || Walled(z)) return SampleWrapped(noise_texture_, 100.0 * x, 100.0 * z);
    // Square paving slabs of 2 m with dark joints and a round stud in each: every slab looks the same. (Slabs
    // shorter than twice the distance driven between frames alias in time: the tracker follows each corner onto the
    // next slab, and with 0.5 m tiles at 0.8 m per frame the ground seemed to move backwards, consistently; no
    // two-view test sees that, see the README.)
    const double period = 2.0;
    const double u = x / period - std::floor(x / period), v = z / period - std::floor(z / period);
    const double joint = std::min({u, 1 - u, v, 1 - v}) * period;  // metres to the nearest joint
    const double stud = std::hypot(u - 0.5, v - 0.5) * period;
    const double joint_shade = std::clamp((joint - 0.04) / 0.02, 0.0, 1.0);
    const double stud_shade = std::clamp((stud - 0.15) / 0.02, 0.0, 1.0);
    return 60.0 + 80.0 * joint_shade * (0.6 + 0.4 * stud_shade);
  }

  double Shade(const Vector3d& origin, const Vector3d& ray) const {
    double nearest = std::numeric_limits<double>::infinity(), grey = 200.0;  // sky
    if (ray.y() > 1e-9) {
      const double t = (kCameraHeight - origin.y()) / ray.y();
      const Vector3d p = origin + t * ray;
      nearest = t;
      grey = GroundGrey(p.x(), p.z());
    }
    if (std::abs(ray.x()) > 1e-9) {
      const double side = ray.x() > 0 ? kWallDistance : -kWallDistance;
      const double t = (side - origin.x()) / ray.x();
      const Vector3d p = origin + t * ray;
      if (t > 0 && t < nearest && p.y() >= kWallTop && p.y() <= kCameraHeight && Walled(p.z())) {
        // Texture units of 2 cm; the left wall shows the texture mirrored.
        const cv::Mat& texture = wall_textures_[p.z() < kOpenBegin ? 0 : 1];
        const double along = 50.0 * (p.z() - (p.z() < kOpenBegin ? -20.0 : kOpenEnd));
        grey = SampleWrapped(texture, side > 0 ? along : 2047.0 - along, 50.0 * (p.y() - kWallTop));
      }
    }
    return grey;
  }

  Ground ground_;
  // 80 degrees of horizontal field of view, as the simulator's camera.
  PerspectiveCamera camera_{kWidth, kHeight, 0.5 * kWidth / std::tan(40.0 * M_PI / 180.0),
                            0.5 * kWidth / std::tan(40.0 * M_PI / 180.0), 0.5 * (kWidth - 1), 0.5 * (kHeight - 1)};
  std::vector<cv::Mat> wall_textures_;
  cv::Mat noise_texture_;
};

struct Taught {
  Map map;
  TeachStatistics statistics;
};

Taught Teach(const Street& street, int every, const TeachOptions& options) {
  Teacher teacher(street.camera(), options, nullptr);
  size_t index = 0;
  for (int k = 0; k < kFrames; k += every) {
    Frame frame = street.Render(k);
    frame.index = index++;
    teacher.AddFrame(frame);
  }
  teacher.Finish();
  return {teacher.map(), teacher.statistics()};
}

// Where the camera sees no wall: the walls before the open stretch leave the 80 degree field of view 4.8 m before
// their end.
bool OnTheOpenStretch(int frame) {
  const double z = kStep * frame;
  return z > kOpenBegin - kWallDistance / std::tan(40.0 * M_PI / 180.0) && z < kOpenEnd;
}

// Arcs whose motion is wrong against the true one (rotation more than 5 degrees or translation direction more than
// 10 degrees off, as a false link of the simulator tests), described; `on_open_stretch` only those with a key-image
// on the open stretch (or across it).
std::vector<std::string> WrongArcs(const Street& street, const Map& map, bool on_open_stretch) {
  std::vector<std::string> wrong;
  for (const MapArc& arc : map.arcs()) {
    const int from = static_cast<int>(map.FindNode(arc.from)->source_frame);
    const int to = static_cast<int>(map.FindNode(arc.to)->source_frame);
    const bool across = (kStep * from < kOpenEnd) != (kStep * to < kOpenEnd);
    if (on_open_stretch && !OnTheOpenStretch(from) && !OnTheOpenStretch(to) && !across) continue;
    const Rigid3d truth = street.WorldFromCamera(to).Inverse() * street.WorldFromCamera(from);
    const double rotation = RotationErrorDeg(arc.to_from_from.rotation, truth.rotation);
    const double direction = AngleBetweenDeg(arc.to_from_from.translation, truth.translation);
    if (rotation > 5.0 || direction > 10.0) {
      wrong.push_back(arc.kind + " arc of frames " + std::to_string(from) + "-" + std::to_string(to) + ": rotation " +
                      std::to_string(rotation) + " deg, direction " + std::to_string(direction) + " deg off");
    }
  }
  return wrong;
}

std::string Join(const std::vector<std::string>& lines) {
  std::string joined;
  for (const std::string& line : lines) joined += line + "\n";
  return joined;
}

// What a teach of the street shows: the pieces of the map and the arcs of the walled stretches.
struct Outcome {
  std::vector<std::string> wrong_arcs;       // on the open stretch
  std::vector<std::string> all_wrong_arcs;
  int arcs_before = 0, arcs_after = 0;  // arcs between key-images of the walled stretches (z <= 12 m, z >= 78 m)
  bool joined_across = false;           // the last key-image before the open stretch and the first after it
  int undetermined_rejections = 0;      // rejected links whose pair does not determine the motion
};

Outcome Examine(const Street& street, const Taught& taught) {
  const Map& map = taught.map;
  Outcome outcome;
  outcome.wrong_arcs = WrongArcs(street, map, true);
  outcome.all_wrong_arcs = WrongArcs(street, map, false);
  const auto z_of = [&](node_t node) { return kStep * map.FindNode(node)->source_frame; };
  std::map<node_t, node_t> piece;
  for (const MapNode& node : map.nodes()) piece[node.id] = node.id;
  const std::function<node_t(node_t)> root = [&](node_t n) { return piece[n] == n ? n : piece[n] = root(piece[n]); };
  for (const MapArc& arc : map.arcs()) {
    piece[root(arc.from)] = root(arc.to);
    if (z_of(arc.to) <= 12.0) ++outcome.arcs_before;
    if (z_of(arc.from) >= 78.0) ++outcome.arcs_after;
  }
  node_t last_before = kInvalidNodeId, first_after = kInvalidNodeId;
  for (const MapNode& node : map.nodes()) {
    if (z_of(node.id) <= 12.0) last_before = node.id;
    if (z_of(node.id) >= 78.0 && first_after == kInvalidNodeId) first_after = node.id;
  }
  outcome.joined_across = last_before != kInvalidNodeId && first_after != kInvalidNodeId &&
                          root(last_before) == root(first_after);
  for (const RejectedLink& rejected : taught.statistics.rejected_links) {
    if (rejected.reason.find("does not determine") != std::string::npos) ++outcome.undetermined_rejections;
  }
  std::cout << map.nodes().size() << " key-images, " << map.arcs().size() << " arcs (" << outcome.arcs_before
            << " before the open stretch, " << outcome.arcs_after << " after), "
            << taught.statistics.rejected_links.size() << " rejected links (" << outcome.undetermined_rejections
            << " undetermined), " << outcome.all_wrong_arcs.size() << " wrong arcs (" << outcome.wrong_arcs.size()
            << " on the open stretch); joined across: " << outcome.joined_across << "\n"
            << Join(outcome.all_wrong_arcs);
  return outcome;
}

// Teach with the tests of TeachOptions that keep undetermined geometry out of the map (one plane's two motions, a
// direction not determined within the link limit) writes no wrong arc on the open stretch, where teach without them
// does (the premise, checked when `premise`: the drive is a real test of them), and reports why.
void ExpectDisconnectedAndRight(const Street& street, int every, bool premise = true) {
  if (std::getenv("RETRACE_DEBUG")) spdlog::set_level(spdlog::level::debug);
  TeachOptions unchecked;
  unchecked.reject_planar_geometry = false;
  unchecked.reject_undetermined_direction = false;
  std::cout << "without the tests: ";
  const Outcome without = Examine(street, Teach(street, every, unchecked));
  if (premise) {
    EXPECT_GE(without.wrong_arcs.size(), 1u) << "the premise: without the tests, teach writes wrong arcs";
  }

  const Outcome outcome = Examine(street, Teach(street, every, TeachOptions()));
  EXPECT_EQ(Join(outcome.wrong_arcs), "");
  EXPECT_FALSE(outcome.joined_across) << "the open stretch leaves the map disconnected";
  EXPECT_GE(outcome.undetermined_rejections, 1) << "and the summary says why";
  EXPECT_GE(outcome.arcs_before, 2) << "the street before it is mapped";
  EXPECT_GE(outcome.arcs_after, 2) << "the street after it is mapped";
}

// Fine noise: without the tests, 4 wrong arcs on the open stretch (gap arcs 52-53 and 54-55, 78 and 54 degrees off;
// tracked 56-57 and 57-58, 16 and 48 degrees). The plane's other motion explains the gap arcs; the tracked arc
// 56-57 (0.8 m, 52 inliers) is merely weak: a direction 10 degrees away lies within its confidence region.
TEST(TeachDegenerate, FeaturelessGroundLeavesTheMapDisconnected) {
  ExpectDisconnectedAndRight(Street(Ground::kFineNoise), 1);
}

// Slabs at 10 frames/s: without the tests the tracked arc of frames 28-29 is 112 degrees off (the plane's other
// motion), and 18-19 (110 degrees) where the walls end.
TEST(TeachDegenerate, RepetitiveTilesLeaveTheMapDisconnected) {
  ExpectDisconnectedAndRight(Street(Ground::kTiles), 1);
}

// At a low frame rate (2.4 m between frames) tracking fails at once after every key-image on the open plane, and
// the images are related by wide-baseline matching (gap arcs). Without the tests three gap arcs on the fine noise are
// written 58, 51 and 12 degrees off; the first is another motion of its plane, the other two (26 and 29 matches, a
// witness confirming them on a second look) leave directions 10 degrees away within their confidence regions.
TEST(TeachDegenerate, FeaturelessGroundAtALowFrameRateLeavesTheMapDisconnected) {
  ExpectDisconnectedAndRight(Street(Ground::kFineNoise), 3);
}

// Slabs 2.4 m apart: without the tests no arc on them is wrong either (the images after their gap candidates do not
// relate to the key-images before, and turn them down), so this drive only checks that the tests keep the map right.
TEST(TeachDegenerate, RepetitiveTilesAtALowFrameRateLeaveTheMapDisconnected) {
  ExpectDisconnectedAndRight(Street(Ground::kTiles), 3, /*premise=*/false);
}

// The test itself on two views with exact ground truth (the true motion as the estimate): points on the ground plane
// do not tell its two motions apart, points on the ground and two walls do.
TEST(PlanarDegeneracy, PlaneAgainstStreet) {
  const PerspectiveCamera camera(kWidth, kHeight, 190.7, 190.7, 159.5, 119.5);
  Rigid3d b_from_a;
  b_from_a.translation = Vector3d(0.05, 0, -1.0).normalized();  // forward and a little to the side
  std::mt19937 random(1);
  std::normal_distribution<double> noise(0.0, 0.2);
  const auto observe = [&](const std::vector<Vector3d>& points, std::vector<Vector3d>* a, std::vector<Vector3d>* b) {
    for (const Vector3d& p : points) {
      Vector2d pa, pb;
      if (!camera.Project(p, &pa) || !camera.Project(b_from_a * p, &pb) || !camera.InImage(pa) ||
          !camera.InImage(pb)) {
        continue;
      }
      Vector3d ba, bb;
      camera.Unproject(pa + Vector2d(noise(random), noise(random)), &ba);
      camera.Unproject(pb + Vector2d(noise(random), noise(random)), &bb);
      a->push_back(ba);
      b->push_back(bb);
    }
  };
  std::uniform_real_distribution<double> across(-6.0, 6.0), ahead(3.0, 30.0), up(-5.0, 1.5);
  std::vector<Vector3d> ground, street;
  for (int i = 0; i < 300; ++i) {
    ground.emplace_back(across(random), kCameraHeight, ahead(random));
    street.push_back(ground.back());
    street.emplace_back(i % 2 ? kWallDistance : -kWallDistance, up(random), ahead(random));
  }
  for (const auto& [name, points, planar] :
       std::vector<std::tuple<std::string, std::vector<Vector3d>, bool>>{{"ground", ground, true},
                                                                         {"street", street, false}}) {
    for (const int n : {20, 40, 300}) {
      std::vector<Vector3d> a, b;
      observe(std::vector<Vector3d>(points.begin(), points.begin() + std::min<size_t>(n, points.size())), &a, &b);
      const PlanarDegeneracy test =
          TestPlanarDegeneracy(a, b, std::vector<bool>(a.size(), true), b_from_a, camera.FocalLength());
      std::cout << name << ", " << a.size() << " points: " << test.homography_inliers << " on one plane, GRIC "
                << test.gric_homography << " (homography) against " << test.gric_essential << ", noise "
                << test.sigma_px << " px; the plane's other motion at " << test.alternative_cost_ratio
                << " times the cost\n";
      EXPECT_EQ(test.ambiguous, planar) << name << ", " << a.size() << " points";
      EXPECT_EQ(test.planar, planar) << name << ", " << a.size() << " points";
    }
  }
}

}  // namespace
}  // namespace retrace
