#include "retrace/teach/map_report.h"

#include <gtest/gtest.h>

#include "retrace/util/testing.h"

namespace retrace {
namespace {

// A linear map of 5 key-images on a curve with known poses: arcs carry unit-length translations and the nodes the
// ratios of consecutive baselines, as teach stores them.
struct KnownRoute {
  std::vector<Rigid3d> world_from_cam;
  Map map;
};

KnownRoute MakeKnownRoute() {
  KnownRoute route;
  for (int i = 0; i < 5; ++i) {
    const double yaw = 0.15 * i;
    const Matrix3d r = Eigen::AngleAxisd(yaw, Vector3d::UnitY()).toRotationMatrix();
    route.world_from_cam.emplace_back(r, Vector3d(3.0 * std::sin(0.3 * i), 0.1 * i, 2.0 * i + 0.5 * i * i));
    MapNode node;
    node.id = i;
    node.source_frame = 7 * i + (i > 2 ? 5 : 0);
    node.image = cv::Mat(40, 60, CV_8UC1, cv::Scalar(20 * i));
    route.map.AddNode(node);
  }
  for (int i = 0; i + 1 < 5; ++i) {
    const Rigid3d to_from_from = route.world_from_cam[i + 1].Inverse() * route.world_from_cam[i];
    MapArc arc;
    arc.id = i;
    arc.from = i;
    arc.to = i + 1;
    arc.to_from_from = Rigid3d(to_from_from.rotation, to_from_from.translation.normalized());
    arc.sigma_p = 1.0 + i;
    for (int j = 0; j < 50 + 10 * i; ++j) arc.points.push_back({100 * i + j, Vector3d(0, 0, 5)});
    route.map.AddArc(arc);
  }
  for (int i = 1; i + 1 < 5; ++i) {
    const double baseline_in = (route.world_from_cam[i].translation - route.world_from_cam[i - 1].translation).norm();
    const double baseline_out = (route.world_from_cam[i + 1].translation - route.world_from_cam[i].translation).norm();
    route.map.AddScale({i, i - 1, i, baseline_out / baseline_in});
  }
  return route;
}

TEST(ChainKeyImagePoses, RecoversKnownPosesUpToTheFirstBaseline) {
  const KnownRoute route = MakeKnownRoute();
  const std::vector<KeyImagePose> chained = ChainKeyImagePoses(route.map);
  ASSERT_EQ(chained.size(), 5u);
  const Rigid3d first_from_world = route.world_from_cam[0].Inverse();
  const double unit = (route.world_from_cam[1].translation - route.world_from_cam[0].translation).norm();
  for (int i = 0; i < 5; ++i) {
    const Rigid3d expected = first_from_world * route.world_from_cam[i];
    EXPECT_EQ(chained[i].node, i);
    EXPECT_LT(RotationErrorDeg(chained[i].world_from_cam.rotation, expected.rotation), 1e-9);
    EXPECT_LT((chained[i].world_from_cam.translation * unit - expected.translation).norm(), 1e-9) << i;
  }
}

TEST(ChainKeyImagePoses, WalksArcsBackwardsToo) {
  // The same route with its arcs reversed (to -> from) must give the same poses.
  const KnownRoute route = MakeKnownRoute();
  Map reversed;
  for (const MapNode& node : route.map.nodes()) reversed.AddNode(node);
  for (const MapArc& arc : route.map.arcs()) {
    MapArc back = arc;
    std::swap(back.from, back.to);
    back.to_from_from = arc.to_from_from.Inverse();
    reversed.AddArc(back);
  }
  for (const NodeScale& s : route.map.scales()) reversed.AddScale(s);
  const auto forward = ChainKeyImagePoses(route.map);
  const auto backward = ChainKeyImagePoses(reversed);
  ASSERT_EQ(backward.size(), forward.size());
  for (size_t i = 0; i < forward.size(); ++i) {
    EXPECT_LT((forward[i].world_from_cam.translation - backward[i].world_from_cam.translation).norm(), 1e-9);
  }
}

TEST(MapStatistics, CountsAndMedians) {
  const KnownRoute route = MakeKnownRoute();
  const MapStatistics stats = ComputeMapStatistics(route.map);
  EXPECT_EQ(stats.num_nodes, 5u);
  EXPECT_EQ(stats.num_arcs, 4u);
  EXPECT_DOUBLE_EQ(stats.min_arc_features, 50.0);
  EXPECT_DOUBLE_EQ(stats.median_arc_features, 70.0);  // 50 60 70 80: upper median
  EXPECT_DOUBLE_EQ(stats.max_sigma_p, 4.0);
  EXPECT_DOUBLE_EQ(stats.median_frames_between_key_images, 7.0);  // 7 7 12 7
}

TEST(MapReport, WritesEveryPlotAndMeasuresTheRoute) {
  const KnownRoute route = MakeKnownRoute();
  std::vector<TimedPose> truth(40);
  for (int i = 0; i < 5; ++i) truth[route.map.nodes()[i].source_frame].world_from_cam = route.world_from_cam[i];
  double expected_length = 0.0;
  for (int i = 1; i < 5; ++i) {
    expected_length += (route.world_from_cam[i].translation - route.world_from_cam[i - 1].translation).norm();
  }
  EXPECT_NEAR(RouteLengthMetres(route.map, truth), expected_length, 1e-9);

  const auto dir = testing::MakeTempDir("map_report");
  MapReportOptions options;
  options.ground_truth = truth;
  options.sigma_p_threshold = 4.0;
  options.min_features = 50;
  const auto written = WriteMapReport(route.map, dir, options);
  EXPECT_EQ(written.size(), 5u);
  for (const auto& path : written) {
    EXPECT_TRUE(std::filesystem::exists(path)) << path;
    EXPECT_GT(std::filesystem::file_size(path), 1000u) << path;
  }
}

}  // namespace
}  // namespace retrace
