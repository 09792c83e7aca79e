// Teach on real data: kitti07 (160 frames, ~90 m of urban road) against the ground-truth poses.

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <unordered_map>
#include <thread>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

#include "retrace/camera/camera_io.h"
#include "retrace/dataset/ground_truth.h"
#include "retrace/dataset/sequence.h"
#include "retrace/image/image_utils.h"
#include "retrace/teach/map_report.h"
#include "retrace/teach/teacher.h"
#include "retrace/util/testing.h"

namespace retrace {
namespace {

struct ArcErrors {
  std::vector<double> rotation_deg;
  std::vector<double> direction_deg;
};

ArcErrors CompareArcsWithGroundTruth(const Map& map, const std::vector<TimedPose>& truth) {
  ArcErrors errors;
  for (const MapArc& arc : map.arcs()) {
    const MapNode* from = map.FindNode(arc.from);
    const MapNode* to = map.FindNode(arc.to);
    const Rigid3d true_to_from_from =
        truth[to->source_frame].world_from_cam.Inverse() * truth[from->source_frame].world_from_cam;
    errors.rotation_deg.push_back(RotationErrorDeg(arc.to_from_from.rotation, true_to_from_from.rotation));
    errors.direction_deg.push_back(AngleBetweenDeg(arc.to_from_from.translation, true_to_from_from.translation));
  }
  return errors;
}

double Median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// Teaches every `every`-th frame of kitti07, on images resized to `width` columns (0: native).
Map TeachKitti(const std::filesystem::path& kitti, size_t every, TeachStatistics* stats, double* sigma_threshold,
               MapDatabase* database = nullptr, const TeachOptions& options = TeachOptions(), int width = 0) {
  std::unique_ptr<Sequence> sequence = OpenSequence(kitti);
  std::unique_ptr<CameraModel> camera = ReadCameraFile(*sequence->calibration_file(), sequence->image_size());
  if (every > 1) sequence = std::make_unique<SubsampledSequence>(std::move(sequence), every, 0);
  if (width > 0) camera = camera->Scaled(static_cast<double>(width) / camera->width());
  Teacher teacher(*camera, options, database);
  while (auto frame = sequence->Next()) {
    if (width > 0) {
      cv::Mat resized;
      ResizeToWidth(frame->image, camera->width(), &resized);
      frame->image = resized;
    }
    teacher.AddFrame(*frame);
  }
  teacher.Finish();
  *stats = teacher.statistics();
  *sigma_threshold = teacher.sigma_p_threshold_px();
  return teacher.map();
}

void CheckKittiMap(const Map& map, const TeachStatistics& stats, double sigma_threshold,
                   const std::vector<TimedPose>& truth) {
  EXPECT_GE(map.nodes().size(), 6u);
  EXPECT_LE(map.nodes().size(), 40u);
  EXPECT_EQ(map.arcs().size() + 1, map.nodes().size()) << "a linear graph: the drive has no loop and no gap";
  EXPECT_FALSE(stats.loop_closed) << "kitti07 frames 0-159 visit no place twice";
  for (const MapArc& arc : map.arcs()) {
    EXPECT_LE(arc.sigma_p, sigma_threshold) << "arc " << arc.id;
    EXPECT_GE(arc.num_features(), 50u) << "arc " << arc.id;
  }
  const ArcErrors errors = CompareArcsWithGroundTruth(map, truth);
  const double max_direction = *std::max_element(errors.direction_deg.begin(), errors.direction_deg.end());
  std::cout << "kitti07 teach: " << map.nodes().size() << " key-images; arc rotation error median "
            << Median(errors.rotation_deg) << " deg, translation direction error median "
            << Median(errors.direction_deg) << " deg, max " << max_direction << " deg\n";
  // Relative scales at the nodes (design §3.3) against the ratio of the true baselines of the two arcs.
  std::vector<double> scale_errors;
  const auto baseline = [&](const MapArc& arc) {
    return (truth[map.FindNode(arc.to)->source_frame].world_from_cam.translation -
            truth[map.FindNode(arc.from)->source_frame].world_from_cam.translation)
        .norm();
  };
  for (const NodeScale& scale : map.scales()) {
    const double true_scale = baseline(*map.FindArc(scale.arc_out)) / baseline(*map.FindArc(scale.arc_in));
    scale_errors.push_back(std::abs(scale.scale / true_scale - 1.0));
  }
  std::cout << "  relative scales at " << scale_errors.size() << " of " << map.nodes().size() - 2
            << " interior nodes, median error " << (scale_errors.empty() ? 0.0 : 100 * Median(scale_errors))
            << " %\n";
  EXPECT_GE(2 * scale_errors.size(), map.nodes().size() - 2);
  ASSERT_FALSE(scale_errors.empty());
  EXPECT_LE(Median(scale_errors), 0.10);
  EXPECT_LE(Median(errors.rotation_deg), 0.3);
  EXPECT_LE(Median(errors.direction_deg), 3.0);
  EXPECT_LE(max_direction, 10.0);
}

TEST(TeachKitti, MapOfAllFramesAgreesWithGroundTruth) {
  RETRACE_REQUIRE_SHARED_DATA(kitti, "kitti07");
  const auto dir = testing::MakeTempDir("teach_kitti");
  auto database = MapDatabase::Create(dir / "route.db");
  TeachStatistics stats;
  double sigma_threshold = 0;
  const Map map = TeachKitti(kitti, 1, &stats, &sigma_threshold, database.get());
  const std::vector<TimedPose> truth = ReadKittiPoses(kitti / "poses.txt");
  CheckKittiMap(map, stats, sigma_threshold, truth);

  // The stored map equals the one in memory, and it is compact: at most 30 kB per metre of route (the paper's
  // figure, design §5).
  database.reset();
  const Map stored = MapDatabase::Open(dir / "route.db")->ReadMap();
  ASSERT_EQ(stored.nodes().size(), map.nodes().size());
  ASSERT_EQ(stored.arcs().size(), map.arcs().size());
  for (size_t i = 0; i < map.arcs().size(); ++i) {
    EXPECT_EQ(stored.arcs()[i].num_features(), map.arcs()[i].num_features());
    // Every feature of an arc is observed in both of its key-images (repeat needs both positions).
    for (const ArcPoint& point : stored.arcs()[i].points) {
      for (const node_t node : {stored.arcs()[i].from, stored.arcs()[i].to}) {
        const auto& features = stored.FindNode(node)->features;
        EXPECT_TRUE(std::any_of(features.begin(), features.end(),
                                [&](const FeatureObservation& f) { return f.feature_id == point.feature_id; }))
            << "feature " << point.feature_id << " of arc " << i << " missing in node " << node;
      }
    }
  }
  const double kilobytes = std::filesystem::file_size(dir / "route.db") / 1000.0;
  const double metres = RouteLengthMetres(map, truth);
  std::cout << "kitti07 map: " << kilobytes << " kB for " << metres << " m = " << kilobytes / metres << " kB/m\n";
  EXPECT_LE(kilobytes / metres, 30.0);
}

TEST(TeachKitti, MapOfEvenFramesAgreesWithGroundTruth) {
  RETRACE_REQUIRE_SHARED_DATA(kitti, "kitti07");
  TeachStatistics stats;
  double sigma_threshold = 0;
  const Map map = TeachKitti(kitti, 2, &stats, &sigma_threshold);
  for (const MapNode& node : map.nodes()) EXPECT_EQ(node.source_frame % 2, 0) << "source frames are original indices";
  CheckKittiMap(map, stats, sigma_threshold, ReadKittiPoses(kitti / "poses.txt"));
}

// A short straight drive (kitti07's even frames 0-38, 4 key-images): the last key-image (frame 38) matches key-image
// 1 (frame 26), 5 m behind it, with 111 inliers, and the witnesses agree (the views are right); only the direction of
// travel shows that the route does not come back there. No loop may be closed.
TEST(TeachKitti, AShortStraightDriveClosesNoLoopBackwards) {
  RETRACE_REQUIRE_SHARED_DATA(kitti, "kitti07");
  std::unique_ptr<Sequence> sequence = OpenSequence(kitti);
  const std::unique_ptr<CameraModel> camera =
      ReadCameraFile(*sequence->calibration_file(), sequence->image_size());
  SubsampledSequence even(std::move(sequence), 2, 0);
  Teacher teacher(*camera, TeachOptions(), nullptr);
  for (size_t i = 0; i < 20; ++i) {
    Frame frame;
    ASSERT_TRUE(even.Read(i, &frame));
    teacher.AddFrame(frame);
  }
  teacher.Finish();
  const Map& map = teacher.map();
  ASSERT_GE(map.nodes().size(), 3u);
  EXPECT_FALSE(teacher.statistics().loop_closed);
  EXPECT_EQ(map.arcs().size() + 1, map.nodes().size()) << "a linear graph";
  const std::vector<RejectedLink>& rejected = teacher.statistics().rejected_links;
  EXPECT_TRUE(std::any_of(rejected.begin(), rejected.end(), [](const RejectedLink& link) {
    return link.kind == "loop" && link.reason.find("goes backwards") != std::string::npos;
  })) << "the backward candidate is reported in teach's summary";
}

TEST(TeachKitti, MappingByMatchingAgreesWithGroundTruth) {
  RETRACE_REQUIRE_SHARED_DATA(kitti, "kitti07");
  TeachOptions options;
  options.method = TeachOptions::Method::kMatching;
  TeachStatistics stats;
  double sigma_threshold = 0;
  const Map map = TeachKitti(kitti, 1, &stats, &sigma_threshold, nullptr, options);
  for (const MapArc& arc : map.arcs()) EXPECT_EQ(arc.kind, "matching");
  CheckKittiMap(map, stats, sigma_threshold, ReadKittiPoses(kitti / "poses.txt"));
}

// Pieces of the map: sets of key-images joined by arcs in either direction.
size_t CountPieces(const Map& map) {
  std::unordered_map<node_t, node_t> parent;
  for (const MapNode& node : map.nodes()) parent[node.id] = node.id;
  const auto root = [&](node_t n) {
    while (parent[n] != n) n = parent[n] = parent[parent[n]];
    return n;
  };
  for (const MapArc& arc : map.arcs()) parent[root(arc.from)] = root(arc.to);
  size_t pieces = 0;
  for (const MapNode& node : map.nodes()) pieces += root(node.id) == node.id;
  return pieces;
}

// A slow camera or a fast car: kitti07 at 320x97 px on every `every`-th frame, where tracking often fails between
// consecutive frames and key-images are related by wide-baseline matching, runs of gap arcs among them, each
// confirmed by the key-image after it (teacher.h). The map must be one piece from the first key-image to the last
// but for the gap arcs `rejected_gaps` (source frames of their key-images), which verification turns down, and every
// arc must agree with the KITTI poses (within 1 degree of rotation and 10 of translation direction, the sim tests'
// limits) but `known_errors`, which are printed.
void CheckSparseKittiMap(const std::filesystem::path& kitti, size_t every, int known_errors,
                         const std::vector<std::pair<int64_t, int64_t>>& rejected_gaps = {}) {
  if (std::getenv("RETRACE_DEBUG")) spdlog::set_level(spdlog::level::debug);
  TeachStatistics stats;
  double sigma_threshold = 0;
  const Map map = TeachKitti(kitti, every, &stats, &sigma_threshold, nullptr, TeachOptions(), 320);
  const std::vector<TimedPose> truth = ReadKittiPoses(kitti / "poses.txt");
  for (const RejectedLink& r : stats.rejected_links) {
    std::cout << "rejected " << r.kind << " link " << r.from << " (frame " << r.from_frame << ") -> " << r.to
              << " (frame " << r.to_frame << "): " << r.reason << "\n";
  }
  const ArcErrors errors = CompareArcsWithGroundTruth(map, truth);
  int gap_arcs = 0, chained_gap_arcs = 0, arcs_off = 0;
  for (size_t i = 0; i < map.arcs().size(); ++i) {
    const MapArc& arc = map.arcs()[i];
    if (arc.kind == "gap") {
      ++gap_arcs;
      chained_gap_arcs += std::any_of(map.arcs().begin(), map.arcs().end(),
                                      [&](const MapArc& a) { return a.from == arc.to && a.kind == "gap"; });
    }
    if (errors.rotation_deg[i] < 1.0 && errors.direction_deg[i] < 10.0) continue;
    ++arcs_off;
    std::cout << arc.kind << " arc " << arc.id << " (frames " << map.FindNode(arc.from)->source_frame << "-"
              << map.FindNode(arc.to)->source_frame << ", " << arc.num_features() << " features, sigma_p "
              << arc.sigma_p << " px): rotation " << errors.rotation_deg[i] << " deg, direction "
              << errors.direction_deg[i] << " deg off the truth\n";
  }
  const size_t pieces = CountPieces(map);
  std::cout << "kitti07 every " << every << (every == 3 ? "rd" : "th") << " frame at 320 px: " << map.nodes().size()
            << " key-images in " << pieces << " piece(s), " << map.arcs().size() << " arcs (" << gap_arcs << " gap, "
            << chained_gap_arcs << " followed by a gap), " << stats.rejected_links.size()
            << " rejected links; arc rotation error median " << Median(errors.rotation_deg) << " deg, max "
            << *std::max_element(errors.rotation_deg.begin(), errors.rotation_deg.end())
            << " deg; translation direction median " << Median(errors.direction_deg) << " deg, max "
            << *std::max_element(errors.direction_deg.begin(), errors.direction_deg.end()) << " deg\n";
  EXPECT_EQ(pieces, 1 + rejected_gaps.size()) << "the map is connected but for the rejected gaps";
  EXPECT_EQ(map.arcs().size() + 1 + rejected_gaps.size(), map.nodes().size()) << "a linear graph";
  ASSERT_EQ(stats.rejected_links.size(), rejected_gaps.size());
  for (size_t i = 0; i < rejected_gaps.size(); ++i) {
    EXPECT_EQ(stats.rejected_links[i].kind, "gap");
    EXPECT_EQ(std::make_pair(stats.rejected_links[i].from_frame, stats.rejected_links[i].to_frame), rejected_gaps[i]);
  }
  EXPECT_GE(chained_gap_arcs, 1) << "the drive has runs of gap arcs";
  EXPECT_LE(arcs_off, known_errors);
  EXPECT_LE(Median(errors.rotation_deg), 0.3);
  EXPECT_LE(Median(errors.direction_deg), 3.0);
}

// 22 of the 36 arcs are gap arcs, 19 of them followed by another. With the verification of links but without the
// key-image after a gap as its witness, the map fell into 20 pieces; without the verification, the gap arc of frames
// 32-36 was 12.5 degrees off (20 samples of its geometry, TeachOptions::min_matched_samples).
TEST(TeachKitti, EveryFourthFrameAt320PxIsOneConnectedRoute) {
  RETRACE_REQUIRE_SHARED_DATA(kitti, "kitti07");
  CheckSparseKittiMap(kitti, 4, 0);
}

// Tracking mostly holds here (5 gap candidates; without the key-image after a gap as witness, the run of frames
// 135-141 was cut twice). The tracked arc of frames 72-75 is off the truth (9 degrees) for reasons of its own pair of
// images, with or without verification: 6 of its 60 features, on the shutters of the facade on the left, are
// tracked onto neighbouring slats, and a wrong motion fits all 60 (the true one puts those 6 behind the camera). The
// gap arc of frames 81-84 is rejected: its motion (translation direction 20 degrees off the truth) fits 143 of the
// 159 matches, the true one 129, and its witness, frame 87 tracked from 84, lies 0.3 degrees from the arc of
// directions any ratio of the two scales allows but 12.9 degrees from the direction at the ratio their 32 shared
// features give (0.45; the truth is near 1); before that check the false arc was kept.
TEST(TeachKitti, EveryThirdFrameAt320PxIsConnectedButForAFalseGap) {
  RETRACE_REQUIRE_SHARED_DATA(kitti, "kitti07");
  CheckSparseKittiMap(kitti, 3, 1, {{81, 84}});
}

TEST(TeachKitti, KilledTeachLeavesAMapThatOpens) {
  RETRACE_REQUIRE_SHARED_DATA(kitti, "kitti07");
  const auto dir = testing::MakeTempDir("teach_kill");
  const auto path = dir / "route.db";
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    std::unique_ptr<Sequence> sequence = OpenSequence(kitti);
    const auto camera = ReadCameraFile(*sequence->calibration_file(), sequence->image_size());
    auto database = MapDatabase::Create(path);
    Teacher teacher(*camera, TeachOptions(), database.get());
    while (auto frame = sequence->Next()) teacher.AddFrame(*frame);
    teacher.Finish();
    _exit(0);
  }
  // Kill the teach process as soon as it has committed three key-images, without warning.
  bool killed = false;
  for (int attempt = 0; attempt < 6000 && !killed; ++attempt) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    try {
      if (std::filesystem::exists(path) && MapDatabase::Open(path)->NumNodes() >= 3) {
        kill(child, SIGKILL);
        killed = true;
      }
    } catch (const std::exception&) {
      // The file may be between creation and its first commit.
    }
  }
  int status = 0;
  waitpid(child, &status, 0);
  ASSERT_TRUE(killed) << "teach finished before it could be killed";
  ASSERT_TRUE(WIFSIGNALED(status));
  const Map map = MapDatabase::Open(path)->ReadMap();
  EXPECT_GE(map.nodes().size(), 3u);
  EXPECT_EQ(map.arcs().size() + 1, map.nodes().size());
  for (const MapArc& arc : map.arcs()) {
    ASSERT_NE(map.FindNode(arc.from), nullptr);
    ASSERT_NE(map.FindNode(arc.to), nullptr);
    EXPECT_FALSE(map.FindNode(arc.to)->image.empty());
  }
}

}  // namespace
}  // namespace retrace
