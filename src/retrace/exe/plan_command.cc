// retrace plan: the shortest path between two key-images of a map's graph (Booij 2007 §B.4; nav/graph_planner.h).

#include <filesystem>
#include <iostream>
#include <stdexcept>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "retrace/exe/commands.h"
#include "retrace/map/map_database.h"
#include "retrace/nav/graph_drawing.h"
#include "retrace/nav/graph_planner.h"
#include "retrace/util/error.h"

namespace retrace {
namespace {

struct PlanArguments {
  std::filesystem::path map_path;
  int64_t from = -1;
  int64_t to = -1;
  std::string cost = "appearance";
  bool directed = false;
  bool json = false;
  std::filesystem::path report_dir;
  PlanOptions options;
};

void RunPlan(const PlanArguments& args) {
  const std::string source = args.map_path.string();
  auto database = MapDatabase::Open(args.map_path);
  const bool need_images = false;
  const Map map = database->ReadMap(need_images);
  for (const int64_t node : {args.from, args.to}) {
    if (map.FindNode(static_cast<node_t>(node)) == nullptr) {
      throw InputError(source, fmt::format("no key-image {} in the map (nodes {}..{})", node,
                                           map.nodes().empty() ? 0 : map.nodes().front().id,
                                           map.nodes().empty() ? -1 : map.nodes().back().id));
    }
  }
  PlanOptions options = args.options;
  options.cost = args.cost == "drive" ? PlanOptions::Cost::kDrive : PlanOptions::Cost::kAppearance;
  options.directed = args.directed;
  PlanningGraph graph;
  try {
    graph = BuildPlanningGraph(map, options);
  } catch (const std::invalid_argument& e) {
    throw InputError(source, e.what());
  }
  const PlannedPath path = PlanPath(graph, static_cast<node_t>(args.from), static_cast<node_t>(args.to));
  if (!args.report_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(args.report_dir, ec);
    const std::filesystem::path file = args.report_dir / "plan.png";
    GraphDrawingOptions drawing;
    drawing.title = fmt::format("plan {} -> {} ({} cost)", args.from, args.to, args.cost);
    if (ec || !cv::imwrite(file.string(), DrawPlanningGraph(map, path, drawing))) {
      throw InputError(file.string(), "cannot write the plan drawing");
    }
    std::cerr << "wrote " << file.string() << "\n";
  }
  if (!path.found) {
    throw InputError(source, fmt::format("no path from key-image {} to {} ({} cost{})", args.from, args.to, args.cost,
                                         args.directed ? ", directed" : ""));
  }
  if (args.json) {
    std::cout << nlohmann::json{{"path", path.nodes}, {"arcs", path.arcs}, {"cost", path.cost}, {"cost_kind", args.cost}}
                     .dump()
              << "\n";
    return;
  }
  std::string nodes;
  for (const node_t n : path.nodes) nodes += fmt::format("{}{}", nodes.empty() ? "" : " ", n);
  std::cout << fmt::format("path from {} to {}: {} key-images, {} arcs, {} cost {:.4g}\n  nodes: {}\n", args.from,
                           args.to, path.nodes.size(), path.arcs.size(), args.cost, path.cost, nodes);
}

}  // namespace

void RegisterPlanCommand(CLI::App& app) {
  auto args = std::make_shared<PlanArguments>();
  CLI::App* cmd = app.add_subcommand(
      "plan", "Shortest path between two key-images over the map's graph (Dijkstra, d = 1 / similarity)");
  cmd->add_option("--map", args->map_path, "Map file written by retrace teach")->required();
  cmd->add_option("--from", args->from, "Start key-image (node id, as in inspect --json)")->required();
  cmd->add_option("--to", args->to, "Goal key-image (node id)")->required();
  cmd->add_option("--cost", args->cost,
                  "appearance: d_ij = 1 / S_ij (Booij 2007 §B.4); drive: seconds of the teach drive between "
                  "key-images (frames when timestamps are equal), loop and join arcs --link-seconds")
      ->check(CLI::IsMember({"appearance", "drive"}))
      ->capture_default_str();
  cmd->add_option("--link-seconds", args->options.link_seconds, "--cost drive: cost of a loop or join arc")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_flag("--directed", args->directed,
                "Drive arcs only forwards (a camera that cannot see backwards); loop and join arcs both ways");
  cmd->add_flag("--json", args->json, R"(Print {"path": [node ids], "arcs": [arc ids], "cost": x, "cost_kind": ...})");
  cmd->add_option("--report", args->report_dir, "Write plan.png: the graph and the path from above");
  cmd->callback([args]() { RunPlan(*args); });
}

}  // namespace retrace
