// retrace inspect: what is in a map — a summary, the whole graph as JSON, or a report of plots.

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <optional>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "retrace/dataset/ground_truth.h"
#include "retrace/exe/commands.h"
#include "retrace/exe/key_image_places.h"
#include "retrace/map/map_database.h"
#include "retrace/nav/graph_drawing.h"
#include "retrace/repeat/map_loading.h"
#include "retrace/teach/map_report.h"
#include "retrace/util/error.h"

namespace retrace {
namespace {

struct InspectArguments {
  std::filesystem::path map_path;
  bool json = false;
  std::filesystem::path report_dir;
  std::vector<std::filesystem::path> ground_truth;  // per route, in route order
};

nlohmann::json MapToJson(const Map& map, const std::map<std::string, std::string>& metadata) {
  nlohmann::json nodes = nlohmann::json::array();
  for (const MapNode& node : map.nodes()) {
    nodes.push_back({{"id", node.id},
                     {"image", node.image_name},
                     {"source_frame", node.source_frame},
                     {"timestamp", node.timestamp},
                     {"route", node.route},
                     {"features", node.features.size()}});
  }
  nlohmann::json arcs = nlohmann::json::array();
  for (const MapArc& arc : map.arcs()) {
    const Matrix3d& r = arc.to_from_from.rotation;
    const Vector3d& t = arc.to_from_from.translation;
    arcs.push_back({{"id", arc.id},
                    {"from", arc.from},
                    {"to", arc.to},
                    {"kind", arc.kind},
                    // Booij 2007 §B.2; null for arcs of maps written before it was stored (schema < 3)
                    {"similarity", arc.similarity ? nlohmann::json(*arc.similarity) : nlohmann::json(nullptr)},
                    {"sigma_p", arc.sigma_p},
                    {"features", arc.num_features()},
                    {"R", {r(0, 0), r(0, 1), r(0, 2), r(1, 0), r(1, 1), r(1, 2), r(2, 0), r(2, 1), r(2, 2)}},
                    {"t", {t.x(), t.y(), t.z()}}});
  }
  nlohmann::json scales = nlohmann::json::array();
  for (const NodeScale& s : map.scales()) {
    scales.push_back({{"node", s.node}, {"arc_in", s.arc_in}, {"arc_out", s.arc_out}, {"scale", s.scale}});
  }
  return {{"nodes", nodes}, {"arcs", arcs}, {"scales", scales}, {"metadata", metadata}};
}

// A finite number written as text, or nothing.
std::optional<double> ParseNumber(const std::string& text) {
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(value)) return std::nullopt;
  return value;
}

// A number stored in the map's metadata; a value that is not one is an error naming the map and the key.
double MetadataNumber(const std::map<std::string, std::string>& metadata, const std::string& key,
                      const std::filesystem::path& map_path) {
  const std::string& text = metadata.at(key);
  const std::optional<double> value = ParseNumber(text);
  if (!value) {
    throw InputError(map_path.string(), "metadata " + key + " is not a number: '" + PrintableText(text, 40) + "'");
  }
  return *value;
}

void RunInspect(const InspectArguments& args) {
  auto database = MapDatabase::Open(args.map_path);
  const bool need_images = !args.report_dir.empty();
  const Map map = database->ReadMap(need_images);
  const auto metadata = database->AllMetadata();
  if (args.json) {
    std::cout << MapToJson(map, metadata).dump() << "\n";
  } else {
    const MapStatistics stats = ComputeMapStatistics(map);
    const auto file_bytes = std::filesystem::file_size(args.map_path);
    std::cout << fmt::format("map {}{}\n", args.map_path.string(),
                             database->complete() ? "" : " (INCOMPLETE: its teach did not finish)");
    std::cout << fmt::format("  key-images      {}\n  arcs            {}\n  features        {}\n", stats.num_nodes,
                             stats.num_arcs, stats.num_features);
    std::cout << fmt::format("  features / arc  median {:.0f}, min {:.0f}\n", stats.median_arc_features,
                             stats.min_arc_features);
    std::cout << fmt::format("  sigma_p         median {:.2f} px, max {:.2f} px\n", stats.median_sigma_p,
                             stats.max_sigma_p);
    int routes = 0, joins = 0;
    std::vector<double> similarities;
    for (const MapNode& node : map.nodes()) routes = std::max(routes, node.route + 1);
    for (const MapArc& arc : map.arcs()) {
      joins += arc.kind == "join";
      if (arc.similarity) similarities.push_back(*arc.similarity);
    }
    std::cout << fmt::format("  routes          {} ({} join arcs between them)\n", routes, joins);
    if (!similarities.empty()) {
      std::sort(similarities.begin(), similarities.end());
      std::cout << fmt::format("  similarity      median {:.3f}, min {:.3f} ({} of {} arcs)\n",
                               similarities[similarities.size() / 2], similarities.front(), similarities.size(),
                               map.arcs().size());
    } else if (!map.arcs().empty()) {
      std::cout << "  similarity      not stored (map written before schema 3)\n";
    }
    std::cout << fmt::format("  spacing         median {:.0f} frames between key-images\n",
                             stats.median_frames_between_key_images);
    std::cout << fmt::format("  size            {:.1f} kB ({:.1f} kB of key-images, {:.1f} kB of relocalization "
                             "signatures)\n",
                             file_bytes / 1000.0, database->ImageBytes() / 1000.0, database->SignatureBytes() / 1000.0);
    // The route's length is for information only (repeat does not read it): a damaged value is shown, not refused.
    if (const auto length = metadata.find("route_length_m"); length != metadata.end()) {
      const std::optional<double> metres = ParseNumber(length->second);
      if (metres && *metres > 0) {
        std::cout << fmt::format("  route           {:.1f} m, {:.1f} kB/m\n", *metres, file_bytes / 1000.0 / *metres);
      } else if (!metres) {
        std::cout << fmt::format("  route           length unreadable: '{}'\n", PrintableText(length->second, 40));
      }
    }
    for (const auto& [key, value] : metadata) {
      if (key == "route_length_m") continue;
      if (key == "ground_fits") {
        // One line per arc (StoreGroundFits): how many, and how many found a ground plane.
        try {
          const auto fits = ParseGroundFits(value, args.map_path.string());
          const auto planes =
              std::count_if(fits.begin(), fits.end(), [](const auto& f) { return f.second.distance_b > 0; });
          std::cout << fmt::format("  {:<15} {} arcs, {} with a ground plane (the metric path's)\n", key, fits.size(),
                                   planes);
        } catch (const InputError& e) {
          std::cout << fmt::format("  {:<15} unreadable ({})\n", key, e.what());
        }
        continue;
      }
      std::cout << fmt::format("  {:<15} {}\n", key, value);
    }
  }
  if (!args.report_dir.empty()) {
    MapReportOptions options;
    // The pose plot compares the first route's key-images with its drive; the graph places every route's.
    KeyImagePlaces places;
    if (!args.ground_truth.empty()) {
      places = ReadKeyImagePlaces(map, args.ground_truth);
      std::error_code ec;
      const std::filesystem::path& first = args.ground_truth.front();
      options.ground_truth = ReadKittiPoses(std::filesystem::is_directory(first, ec) ? first / "poses.txt" : first);
    }
    if (metadata.count("r_p") != 0) options.sigma_p_threshold = MetadataNumber(metadata, "r_p", args.map_path);
    if (metadata.count("min_features") != 0) {
      options.min_features = MetadataNumber(metadata, "min_features", args.map_path);
    }
    for (const auto& path : WriteMapReport(map, args.report_dir, options)) {
      std::cerr << "wrote " << path.string() << "\n";
    }
    // The graph from above, arcs shaded by similarity (Booij 2007 Fig. B.5; nav/graph_drawing.h).
    const std::filesystem::path graph = args.report_dir / "graph.png";
    GraphDrawingOptions drawing;
    drawing.title = "graph of " + args.map_path.filename().string();
    drawing.positions = places.positions;
    drawing.x_label = places.x_label;
    drawing.y_label = places.y_label;
    if (!cv::imwrite(graph.string(), DrawPlanningGraph(map, PlannedPath(), drawing))) {
      throw InputError(graph.string(), "cannot write the graph drawing");
    }
    std::cerr << "wrote " << graph.string() << "\n";
  }
}

}  // namespace

void RegisterInspectCommand(CLI::App& app) {
  auto args = std::make_shared<InspectArguments>();
  CLI::App* cmd = app.add_subcommand("inspect", "Summarize a map; --json prints the graph, --report DIR draws plots");
  cmd->add_option("--map", args->map_path, "Map file written by retrace teach")->required();
  cmd->add_flag("--json", args->json, "Print nodes and arcs as one JSON object");
  cmd->add_option("--report", args->report_dir, "Write plots (features and sigma_p per arc, spacing, key-images, poses, the graph with its similarities)");
  cmd->add_option("--ground-truth", args->ground_truth,
                  "Ground truth of the teach drives, one per route in route order (KITTI poses.txt or its sequence "
                  "folder; simulated drives in the town's frame by their scenario.yaml): the pose plot of route 0 and "
                  "the graph at the key-images' true places");
  cmd->callback([args]() { RunInspect(*args); });
}

}  // namespace retrace
