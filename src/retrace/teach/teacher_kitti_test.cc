// Teach on real data: kitti07 (160 frames, ~90 m of urban road) against the ground-truth poses.

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <thread>

#include <gtest/gtest.h>

#include "retrace/camera/camera_io.h"
#include "retrace/dataset/ground_truth.h"
#include "retrace/dataset/sequence.h"
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

Map TeachKitti(const std::filesystem::path& kitti, size_t every, TeachStatistics* stats, double* sigma_threshold,
               MapDatabase* database = nullptr, const TeachOptions& options = TeachOptions()) {
  std::unique_ptr<Sequence> sequence = OpenSequence(kitti);
  const auto camera = ReadCameraFile(*sequence->calibration_file(), sequence->image_size());
  if (every > 1) sequence = std::make_unique<SubsampledSequence>(std::move(sequence), every, 0);
  Teacher teacher(*camera, options, database);
  while (auto frame = sequence->Next()) teacher.AddFrame(*frame);
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
