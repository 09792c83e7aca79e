#include "retrace/nav/graph_drawing.h"

#include <algorithm>
#include <unordered_map>
#include <unordered_set>

#include <fmt/format.h>

#include "retrace/teach/map_report.h"
#include "retrace/viz/plot.h"

namespace retrace {

cv::Mat DrawPlanningGraph(const Map& map, const PlannedPath& path, const GraphDrawingOptions& options) {
  // From above: the first key-image's camera frame has x right, y down, z forward; the plot shows x and z.
  const bool given = !options.positions.empty();
  std::unordered_map<node_t, Vector2d> position = options.positions;
  if (!given) {
    for (const KeyImagePose& pose : ChainKeyImagePoses(map)) {
      const Vector3d& c = pose.world_from_cam.translation;
      position[pose.node] = Vector2d(c.x(), c.z());
    }
  }
  std::vector<PlotSeries> series;
  const auto segment = [&](node_t a, node_t b, const cv::Scalar& color, int thickness, const std::string& label) {
    const auto pa = position.find(a), pb = position.find(b);
    if (pa == position.end() || pb == position.end()) return;
    PlotSeries s;
    s.label = label;
    s.x = {pa->second.x(), pb->second.x()};
    s.y = {pa->second.y(), pb->second.y()};
    s.color = color;
    s.thickness = thickness;
    series.push_back(std::move(s));
  };
  bool labelled_arc = false, labelled_join = false;
  for (const MapArc& arc : map.arcs()) {
    // Darker = more similar (paper Fig. B.5); unknown similarity in mid grey.
    const double similarity = arc.similarity ? std::clamp(*arc.similarity * 4.0, 0.0, 1.0) : 0.5;
    const bool join = arc.kind == "join";
    const double light = 220.0 * (1.0 - similarity);
    const cv::Scalar color = join ? cv::Scalar(light, 200, light) : cv::Scalar(light, light, light);
    std::string label;
    if (join && !labelled_join) {
      label = "join arcs (darker: more similar)";
      labelled_join = true;
    } else if (!join && !labelled_arc) {
      label = "route arcs (darker: more similar)";
      labelled_arc = true;
    }
    segment(arc.from, arc.to, color, join ? 2 : 2, label);
  }
  for (size_t i = 0; i + 1 < path.nodes.size(); ++i) {
    segment(path.nodes[i], path.nodes[i + 1], cv::Scalar(30, 30, 220), 4,
            i == 0 ? fmt::format("planned path, cost {:.2f}", path.cost) : "");
  }
  std::unordered_map<int, PlotSeries> routes;
  for (const MapNode& node : map.nodes()) {
    const auto p = position.find(node.id);
    if (p == position.end()) continue;
    PlotSeries& s = routes[node.route];
    s.label = fmt::format("key-images of route {}", node.route);
    s.style = PlotSeries::Style::kPoints;
    s.color = SeriesColor(node.route);
    s.thickness = 3;
    s.x.push_back(p->second.x());
    s.y.push_back(p->second.y());
  }
  std::vector<int> route_ids;
  for (const auto& entry : routes) route_ids.push_back(entry.first);
  std::sort(route_ids.begin(), route_ids.end());
  for (const int r : route_ids) series.push_back(routes[r]);
  if (path.found && !path.nodes.empty()) {
    for (const auto& [node, label, color] :
         {std::make_tuple(path.nodes.front(), "start", cv::Scalar(0, 160, 0)),
          std::make_tuple(path.nodes.back(), "goal", cv::Scalar(0, 0, 200))}) {
      const auto p = position.find(node);
      if (p == position.end()) continue;
      PlotSeries s;
      s.label = fmt::format("{} (node {})", label, node);
      s.style = PlotSeries::Style::kPoints;
      s.color = color;
      s.thickness = 8;
      s.x = {p->second.x()};
      s.y = {p->second.y()};
      series.push_back(std::move(s));
    }
  }
  PlotOptions plot;
  plot.width = options.width;
  plot.height = options.height;
  plot.title = given ? fmt::format("{}: {} key-images at their ground truth, {} arcs", options.title,
                                   map.nodes().size(), map.arcs().size())
                     : fmt::format("{}: {} key-images ({} placed by chaining arcs), {} arcs", options.title,
                                   map.nodes().size(), position.size(), map.arcs().size());
  plot.x_label = given ? options.x_label : "x (units of the first arc, chained)";
  plot.y_label = given ? options.y_label : "z (forward of the first key-image)";
  plot.equal_aspect = true;
  return RenderPlot(series, plot);
}

}  // namespace retrace
