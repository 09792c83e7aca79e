#include "retrace/teach/map_report.h"

#include <algorithm>
#include <deque>
#include <set>
#include <unordered_map>

#include <Eigen/Geometry>
#include <opencv2/imgcodecs.hpp>

#include "retrace/image/image_utils.h"
#include "retrace/util/error.h"
#include "retrace/viz/plot.h"

namespace retrace {
namespace {

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + mid, values.end());
  return values[mid];
}

void WritePng(const std::filesystem::path& path, const cv::Mat& image, std::vector<std::filesystem::path>* written) {
  if (!cv::imwrite(path.string(), image)) throw InputError(path.string(), "cannot write image");
  written->push_back(path);
}

}  // namespace

std::vector<KeyImagePose> ChainKeyImagePoses(const Map& map) {
  std::vector<KeyImagePose> poses;
  if (map.nodes().empty()) return poses;
  // Breadth-first over arcs in both directions; `unit` is the factor from an arc's unit to the first arc's unit.
  struct Reached {
    Rigid3d world_from_cam;
    arc_t via_arc = kInvalidArcId;
    double unit = 1.0;
  };
  std::unordered_map<node_t, Reached> reached;
  std::deque<node_t> queue;
  const node_t first = map.nodes().front().id;
  reached[first] = Reached();
  queue.push_back(first);
  while (!queue.empty()) {
    const node_t node = queue.front();
    queue.pop_front();
    const Reached here = reached[node];
    const auto unit_of = [&](const MapArc& arc) {
      if (here.via_arc == kInvalidArcId) return 1.0;
      // Scale stored at `node` between the arc we came by and this one, in either order.
      if (const auto s = map.ScaleAt(node, here.via_arc, arc.id)) return here.unit * *s;
      if (const auto s = map.ScaleAt(node, arc.id, here.via_arc); s && *s != 0.0) return here.unit / *s;
      return here.unit;
    };
    for (const MapArc* arc : map.ArcsFrom(node)) {
      if (reached.count(arc->to) != 0) continue;
      const double unit = unit_of(*arc);
      const Rigid3d to_from_from(arc->to_from_from.rotation, unit * arc->to_from_from.translation);
      reached[arc->to] = {here.world_from_cam * to_from_from.Inverse(), arc->id, unit};
      queue.push_back(arc->to);
    }
    for (const MapArc* arc : map.ArcsTo(node)) {
      if (reached.count(arc->from) != 0) continue;
      const double unit = unit_of(*arc);
      const Rigid3d to_from_from(arc->to_from_from.rotation, unit * arc->to_from_from.translation);
      reached[arc->from] = {here.world_from_cam * to_from_from, arc->id, unit};
      queue.push_back(arc->from);
    }
  }
  for (const MapNode& node : map.nodes()) {
    if (const auto it = reached.find(node.id); it != reached.end()) poses.push_back({node.id, it->second.world_from_cam});
  }
  return poses;
}

MapStatistics ComputeMapStatistics(const Map& map) {
  MapStatistics stats;
  stats.num_nodes = map.nodes().size();
  stats.num_arcs = map.arcs().size();
  std::set<feature_t> ids;
  for (const MapNode& node : map.nodes()) {
    for (const FeatureObservation& f : node.features) ids.insert(f.feature_id);
  }
  stats.num_features = ids.size();
  std::vector<double> features, sigma_p, spacing;
  for (const MapArc& arc : map.arcs()) {
    features.push_back(static_cast<double>(arc.num_features()));
    sigma_p.push_back(arc.sigma_p);
    const MapNode* from = map.FindNode(arc.from);
    const MapNode* to = map.FindNode(arc.to);
    if (from != nullptr && to != nullptr && arc.kind != "loop") {
      spacing.push_back(static_cast<double>(std::abs(to->source_frame - from->source_frame)));
    }
  }
  stats.median_arc_features = Median(features);
  stats.min_arc_features = features.empty() ? 0.0 : *std::min_element(features.begin(), features.end());
  stats.median_sigma_p = Median(sigma_p);
  stats.max_sigma_p = sigma_p.empty() ? 0.0 : *std::max_element(sigma_p.begin(), sigma_p.end());
  stats.median_frames_between_key_images = Median(spacing);
  return stats;
}

double RouteLengthMetres(const Map& map, const std::vector<TimedPose>& ground_truth) {
  double length = 0.0;
  const Vector3d* previous = nullptr;
  Vector3d last;
  for (const MapNode& node : map.nodes()) {
    if (node.source_frame < 0 || node.source_frame >= static_cast<int64_t>(ground_truth.size())) continue;
    const Vector3d position = ground_truth[node.source_frame].world_from_cam.translation;
    if (previous != nullptr) length += (position - last).norm();
    last = position;
    previous = &last;
  }
  return length;
}

std::vector<std::filesystem::path> WriteMapReport(const Map& map, const std::filesystem::path& directory,
                                                  const MapReportOptions& options) {
  std::error_code ec;
  std::filesystem::create_directories(directory, ec);
  if (ec) throw InputError(directory.string(), "cannot create report folder: " + ec.message());
  std::vector<std::filesystem::path> written;

  // Features and σ_p per arc (paper Figs. 9-10).
  PlotSeries features{"features |M_k|", {}, {}, PlotSeries::Style::kBars, SeriesColor(0)};
  PlotSeries sigma_p{"sigma_p [px]", {}, {}, PlotSeries::Style::kLinePoints, SeriesColor(1)};
  for (const MapArc& arc : map.arcs()) {
    features.x.push_back(static_cast<double>(arc.id));
    features.y.push_back(static_cast<double>(arc.num_features()));
    sigma_p.x.push_back(static_cast<double>(arc.id));
    sigma_p.y.push_back(arc.sigma_p);
  }
  PlotOptions features_plot;
  features_plot.title = "Features per arc";
  features_plot.x_label = "arc";
  features_plot.y_label = "features";
  if (options.min_features > 0) features_plot.reference_lines.push_back({options.min_features, "n"});
  WritePng(directory / "arc_features.png", RenderPlot({features}, features_plot), &written);
  PlotOptions sigma_plot;
  sigma_plot.title = "Geometry quality per arc";
  sigma_plot.x_label = "arc";
  sigma_plot.y_label = "sigma_p [px]";
  sigma_plot.y_min = 0.0;
  if (options.sigma_p_threshold > 0) sigma_plot.reference_lines.push_back({options.sigma_p_threshold, "r_p"});
  WritePng(directory / "arc_sigma_p.png", RenderPlot({sigma_p}, sigma_plot), &written);

  // Key-image spacing along the sequence (paper Fig. 11).
  PlotSeries spacing{"frames between key-images", {}, {}, PlotSeries::Style::kBars, SeriesColor(2)};
  for (size_t i = 1; i < map.nodes().size(); ++i) {
    spacing.x.push_back(static_cast<double>(map.nodes()[i].source_frame));
    spacing.y.push_back(static_cast<double>(map.nodes()[i].source_frame - map.nodes()[i - 1].source_frame));
  }
  PlotOptions spacing_plot;
  spacing_plot.title = "Key-image spacing";
  spacing_plot.x_label = "teach frame of the key-image";
  spacing_plot.y_label = "frames since previous";
  WritePng(directory / "key_image_spacing.png", RenderPlot({spacing}, spacing_plot), &written);

  // Contact sheet of the key-images.
  std::vector<cv::Mat> images;
  std::vector<std::string> labels;
  for (const MapNode& node : map.nodes()) {
    if (node.image.empty()) continue;
    images.push_back(node.image);
    labels.push_back("node " + std::to_string(node.id) + "  frame " + std::to_string(node.source_frame));
  }
  if (!images.empty()) {
    WritePng(directory / "key_images.png", MakeContactSheet(images, labels, 4, options.thumbnail_width), &written);
  }

  // Key-image poses from above (x right, z forward), chained from the map, aligned to ground truth when given.
  const std::vector<KeyImagePose> chained = ChainKeyImagePoses(map);
  PlotSeries map_track{"key-images (map, chained)", {}, {}, PlotSeries::Style::kLinePoints, SeriesColor(0)};
  PlotSeries truth_track{"ground truth", {}, {}, PlotSeries::Style::kLine, SeriesColor(3)};
  PlotSeries truth_nodes{"", {}, {}, PlotSeries::Style::kPoints, SeriesColor(3)};
  std::vector<Vector3d> chained_positions, true_positions;
  for (const KeyImagePose& pose : chained) {
    const MapNode* node = map.FindNode(pose.node);
    // The ground truth is the first drive's: the key-images of appended routes count frames of their own drives.
    if (options.ground_truth && node->route == 0 && node->source_frame >= 0 &&
        node->source_frame < static_cast<int64_t>(options.ground_truth->size())) {
      chained_positions.push_back(pose.world_from_cam.translation);
      true_positions.push_back((*options.ground_truth)[node->source_frame].world_from_cam.translation);
    }
  }
  Eigen::Matrix4d truth_from_map = Eigen::Matrix4d::Identity();
  if (chained_positions.size() >= 3) {
    Eigen::Matrix3Xd src(3, chained_positions.size()), dst(3, true_positions.size());
    for (size_t i = 0; i < chained_positions.size(); ++i) {
      src.col(i) = chained_positions[i];
      dst.col(i) = true_positions[i];
    }
    truth_from_map = Eigen::umeyama(src, dst, /*with_scaling=*/true);
  }
  for (const KeyImagePose& pose : chained) {
    const Vector3d p = (truth_from_map * pose.world_from_cam.translation.homogeneous()).head<3>();
    map_track.x.push_back(p.x());
    map_track.y.push_back(p.z());
  }
  if (options.ground_truth) {
    for (const TimedPose& pose : *options.ground_truth) {
      truth_track.x.push_back(pose.world_from_cam.translation.x());
      truth_track.y.push_back(pose.world_from_cam.translation.z());
    }
    for (const Vector3d& p : true_positions) {
      truth_nodes.x.push_back(p.x());
      truth_nodes.y.push_back(p.z());
    }
  }
  PlotOptions poses_plot;
  poses_plot.title = options.ground_truth ? "Key-image poses from above (similarity-aligned to ground truth)"
                                          : "Key-image poses from above (unit: first arc)";
  poses_plot.x_label = options.ground_truth ? "x [m]" : "x";
  poses_plot.y_label = options.ground_truth ? "z [m]" : "z";
  poses_plot.equal_aspect = true;
  poses_plot.height = 600;
  WritePng(directory / "key_image_poses.png", RenderPlot({truth_track, truth_nodes, map_track}, poses_plot),
           &written);
  return written;
}

}  // namespace retrace
