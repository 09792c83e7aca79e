// `retrace sim ...`: the simulator. Renders drives through the built-in procedural town into KITTI-layout
// sequences (images, calibration, timestamps, ground-truth poses), and prints a documented example scenario.

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>

#include <nlohmann/json.hpp>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <spdlog/spdlog.h>

#include "retrace/dataset/ground_truth.h"
#include "retrace/drive/closed_loop.h"
#include "retrace/drive/navigation_loop.h"
#include "retrace/map/map_database.h"
#include "retrace/repeat/evaluation.h"
#include "retrace/repeat/map_loading.h"
#include "retrace/exe/commands.h"
#include "retrace/exe/key_image_places.h"
#include "retrace/exe/sequence_input.h"
#include "retrace/sim/recording.h"
#include "retrace/sim/scenario_io.h"
#include "retrace/sim/simulator.h"
#include "retrace/util/error.h"
#include "retrace/util/progress.h"
#include "retrace/viz/plot.h"

namespace retrace {

namespace {

// Applies the command line's overrides to the scenario read from `scenario_file` ("" = the built-in scenario) and
// checks the result (Scenario::Check, the one check of scenario files and options). Throws a one-line InputError.
Scenario ReadScenarioWithOverrides(const std::string& scenario_file, const ScenarioOverrides& overrides) {
  Scenario scenario = scenario_file.empty() ? Scenario() : ReadScenario(scenario_file);
  if (const std::string bad = overrides.Apply(&scenario); !bad.empty()) {
    // A bad option names itself; a key of the file that no longer fits the options is the file's.
    throw InputError(bad.rfind("--", 0) == 0 || scenario_file.empty() ? "" : scenario_file, bad);
  }
  return scenario;
}

// Largest frame count of a recording (the range of `frames`): also the bound of a whole route's frames.
int MaxFrames() { return static_cast<int>(FindScenarioKeyRange("frames")->max); }

// The documented range of a scenario key for an option's help ("0..1000").
std::string RangeOf(const char* key) { return FindScenarioKeyRange(key)->Text(); }

// The scenario overrides shared by `sim render` and `sim drive` (ScenarioOverrides; unset unless given).
struct ScenarioArguments {
  std::string scenario;
  int width = 0;
  int height = 0;
  int64_t seed = -1;
  std::string route;
  int segments = 0;
  double frame_rate = 0.0;
  int pedestrians = 0;
  std::string lighting;
  std::string repeat_lighting;
  double lateral_offset = 0.0;
  int threads = 0;

  // Registers --scenario, --width ... --threads on `command`.
  void Register(CLI::App* command);
  // The overrides of the options given on `command`.
  ScenarioOverrides Overrides(const CLI::App& command) const;
};

void ScenarioArguments::Register(CLI::App* command) {
  const Scenario defaults;
  std::string presets;
  for (const LightingPreset& p : LightingPresets()) {
    presets += fmt::format("{}{} ({})", presets.empty() ? "" : ", ", p.name, p.description);
  }
  command->add_option("--scenario", scenario, "Scenario file (YAML/JSON); default: the built-in scenario");
  command->add_option("--width", width,
                      "Image width, " + RangeOf("camera.width") + "; overrides the scenario (keeps the field of view)");
  command->add_option("--height", height, "Image height, " + RangeOf("camera.height") + "; overrides the scenario");
  command->add_option("--seed", seed, "Seed of the drive and the town; overrides the scenario");
  command->add_option("--route", route,
                      fmt::format("Route type: auto (seeded, --segments streets), loop (around blocks) or crossing (a "
                                  "figure eight that crosses itself); default {}",
                                  defaults.route.type));
  command->add_option("--segments", segments,
                      fmt::format("Streets of an auto route (about 60 m each), {}; default {}",
                                  RangeOf("route.segments"), defaults.route.segments));
  command->add_option("--frame-rate", frame_rate,
                      fmt::format("Frames per second, {}; default {}", RangeOf("frame_rate"), defaults.frame_rate));
  command->add_option("--pedestrians", pedestrians,
                      fmt::format("Walking pedestrians in the town, {}; default {}", RangeOf("town.pedestrians"),
                                  defaults.town.num_pedestrians));
  command->add_option("--lighting", lighting,
                      "Light of the teach drive (sun, sky and exposure): " + presets +
                          "; default the scenario's (sun at 160 deg, 55 deg high)");
  command->add_option("--repeat-lighting", repeat_lighting,
                      "Light of the repeat variant, as --lighting; default the scenario's (sun at 250 deg, 25 deg "
                      "high)");
  command->add_option("--lateral-offset", lateral_offset,
                      fmt::format("Repeat variant: distance right of the teach drive, {}; default {}",
                                  RangeOf("repeat.lateral_offset"), defaults.repeat.lateral_offset));
  command->add_option("--threads", threads,
                      fmt::format("Render threads, {}; overrides the scenario (default {})", RangeOf("render.threads"),
                                  defaults.render.num_threads));
}

ScenarioOverrides ScenarioArguments::Overrides(const CLI::App& command) const {
  const auto given = [&](const char* name) { return command.get_option(name)->count() > 0; };
  ScenarioOverrides overrides;
  if (given("--width")) overrides.width = width;
  if (given("--height")) overrides.height = height;
  if (given("--seed")) overrides.seed = seed;
  if (given("--route")) overrides.route = route;
  if (given("--segments")) overrides.segments = segments;
  if (given("--frame-rate")) overrides.frame_rate = frame_rate;
  if (given("--pedestrians")) overrides.pedestrians = pedestrians;
  if (given("--lighting")) overrides.lighting = lighting;
  if (given("--repeat-lighting")) overrides.repeat_lighting = repeat_lighting;
  if (given("--lateral-offset")) overrides.lateral_offset = lateral_offset;
  if (given("--threads")) overrides.threads = threads;
  return overrides;
}

struct RenderArguments {
  ScenarioArguments scenario;
  std::string out;
  std::string bag;
  std::string variant = "teach";
  int frames = -1;
  double speed = 0.0;
  std::string contact_sheet;
  int sheet_every = 10;
  bool quiet = false;
  std::string poses;  // render at these camera poses (KITTI poses.txt) instead of driving
};

// `sim render`: a teach or repeat drive of the scenario with the command line's overrides.
void RunRender(const CLI::App& command, const RenderArguments& args) {
  const auto given = [&](const char* name) { return command.get_option(name)->count() > 0; };
  if (given("--contact-sheet-every") && !(args.sheet_every >= 1 && args.sheet_every <= MaxFrames())) {
    throw InputError("", fmt::format("--contact-sheet-every: must be in 1..{}, got {}", MaxFrames(), args.sheet_every));
  }
  ScenarioOverrides overrides = args.scenario.Overrides(command);
  if (given("--frames")) overrides.frames = args.frames;
  if (given("--speed")) overrides.max_speed = args.speed;
  const Scenario scenario = ReadScenarioWithOverrides(args.scenario.scenario, overrides);
  const ScenarioVariant v = args.variant == "repeat" ? ScenarioVariant::kRepeat : ScenarioVariant::kTeach;
  Simulator simulator(ApplyVariant(scenario, v));
  if (simulator.ExpectedFrames() > MaxFrames()) {
    throw InputError(args.scenario.scenario,
                     fmt::format("the route ({:.0f} m) takes about {} frames at {} Hz, more than {}: set frames "
                                 "(--frames) or a shorter route",
                                 simulator.route().length(), simulator.ExpectedFrames(), scenario.frame_rate,
                                 MaxFrames()));
  }
  RecordOptions options;
  options.progress = !args.quiet;
  options.contact_sheet = args.contact_sheet;
  options.contact_sheet_every = std::max(1, args.sheet_every);
  if (!args.poses.empty()) {
    // At given poses: KITTI poses.txt in the simulator's world frame (the camera at the route's start), the frame
    // rate's clock for the moving occluders.
    std::vector<TimedPose> poses = ReadKittiPoses(args.poses);
    if (poses.empty()) throw InputError(args.poses, "no poses");
    if (poses.size() > static_cast<size_t>(MaxFrames())) {
      throw InputError(args.poses, fmt::format("{} poses, more than {}", poses.size(), MaxFrames()));
    }
    for (size_t i = 0; i < poses.size(); ++i) poses[i].timestamp = scenario.time_offset + i / scenario.frame_rate;
    const RecordSummary summary = RecordPoses(&simulator, poses, args.out, options);
    std::cout << fmt::format("wrote {} frames at the poses of {} to {} in {:.1f} s\n", summary.frames, args.poses,
                             args.out, summary.seconds);
    return;
  }
  const RecordSummary summary = args.bag.empty() ? RecordSequence(&simulator, args.out, options)
                                                 : RecordSimulatedBag(&simulator, args.bag, options);
  std::cout << fmt::format("wrote {} frames ({:.0f} m of a {:.0f} m route, {} variant) to {} in {:.1f} s ({:.1f} "
                           "fps)\n",
                           summary.frames, summary.driven_m, summary.route_length_m, args.variant,
                           args.bag.empty() ? args.out : args.bag,
                           summary.seconds, summary.frames / std::max(1e-9, summary.seconds));
  if (summary.stopped_at_route_end) {
    std::cout << fmt::format("the route ends after {} frames: {} fewer than the {} asked for (frames 0 drives the "
                             "whole route)\n",
                             summary.frames, summary.frames_requested - summary.frames, summary.frames_requested);
  }
  if (!args.contact_sheet.empty()) std::cout << "contact sheet: " << args.contact_sheet << "\n";
}

struct DriveArguments {
  ScenarioArguments scenario;
  std::string map;
  std::string out;
  std::string taught_poses;
  bool quiet = false;
  std::string control = "path";
  double camera_height = -1;  // default: the scenario's vehicle
  double camera_forward = -1;
  // Where the drive starts: this arc (-1: the first arc of the taught route, where the scenario's repeat starts), or
  // found by retrieval over the whole map (no_start_arc, a robot that does not know where it was put down).
  arc_t start_arc = kInvalidArcId;
  bool no_start_arc = false;
  // The localizer's options (LocalizerOptions): its defaults unless given.
  bool placed_start_fine = LocalizerOptions().tracker.placed_features_start_fine;
  bool affine_refine = LocalizerOptions().affine_refinement;
  bool verified_placement = LocalizerOptions().place_by_verified_key_images;
  bool multi_view_points = LocalizerOptions().multi_view_points;
  bool relocalization_affine = false;  // LocalizerOptions::relocalization_affine_fallback
  bool robust_relocalization = LocalizerOptions().relocalization_robust_alignment;
  int travel_window = TaughtPathOptions().travel_window;
  int guided_matching = LocalizerOptions().guided_matching_min_inliers;
  int start_alternative_starts = LocalizerOptions().start_alternative_starts;
  ClosedLoopOptions drive;
};

// `sim drive`: the repeat variant of the scenario driven by the localizer's steering (closed loop).
void RunDrive(const CLI::App& command, const DriveArguments& args) {
  const Scenario scenario = ReadScenarioWithOverrides(args.scenario.scenario, args.scenario.Overrides(command));
  // The robot's geometry, as a user would measure it: the simulated car's unless given; a control step per frame.
  ClosedLoopOptions drive = args.drive;
  drive.frame_period = 1.0 / scenario.frame_rate;
  drive.control = args.control == "eq10" ? ClosedLoopControl::kImage : ClosedLoopControl::kPath;
  drive.tracking.camera_forward = args.camera_forward > 0 ? args.camera_forward : scenario.vehicle.camera_forward;
  std::string error;
  if (!drive.Check(&error)) throw InputError("sim drive options", error);
  const std::vector<TimedPose> taught =
      args.taught_poses.empty() ? std::vector<TimedPose>() : ReadKittiPoses(args.taught_poses);

  LocalizerOptions base;
  base.path.camera_height = args.camera_height > 0 ? args.camera_height : scenario.vehicle.camera_height;
  base.tracker.placed_features_start_fine = args.placed_start_fine;
  base.affine_refinement = args.affine_refine;
  base.place_by_verified_key_images = args.verified_placement;
  base.multi_view_points = args.multi_view_points;
  base.relocalization_affine_fallback = args.relocalization_affine;
  base.relocalization_robust_alignment = args.robust_relocalization;
  base.path.travel_window = args.travel_window;
  base.guided_matching_min_inliers = args.guided_matching;
  base.start_alternative_starts = args.start_alternative_starts;
  MapForLocalizer loaded = LoadMapForLocalizer(args.map, base);
  Simulator simulator(ApplyVariant(scenario, ScenarioVariant::kRepeat));
  const CameraModel& camera = simulator.camera();
  const cv::Size key_image = loaded.key_image_size;
  if (key_image.width != camera.width() || key_image.height != camera.height()) {
    throw InputError(args.map, fmt::format("key-images are {}x{} but the scenario's camera is {}x{} (--width, "
                                           "--height)",
                                           key_image.width, key_image.height, camera.width(), camera.height()));
  }
  Localizer localizer(std::move(loaded.map), camera, loaded.options);
  // A teach-and-repeat robot repeats its route from where the route starts (Segvic 2009 §3.3): the localizer is
  // told the start arc, as `repeat --start-arc`.
  if (!args.no_start_arc) {
    arc_t start_arc = args.start_arc;
    if (start_arc == kInvalidArcId) {
      const std::vector<arc_t> route = RouteArcs(localizer.map());
      if (!route.empty()) start_arc = route.front();
    }
    if (start_arc != kInvalidArcId) {
      if (localizer.map().FindArc(start_arc) == nullptr) {
        throw InputError(args.map, fmt::format("--start-arc {}: the map has no such arc", start_arc));
      }
      localizer.SetStartArc(start_arc);
    }
  }

  std::filesystem::create_directories(args.out);
  const std::filesystem::path csv_path = std::filesystem::path(args.out) / "drive.csv";
  std::ofstream csv(csv_path);
  if (!csv) throw InputError(csv_path.string(), "cannot be written");
  csv << "frame,timestamp,x,z,heading,state,arc,tracked,steering,wheels,deviation,along,ms,mode,curvature,speed,"
         "lateral_m,heading_error_rad,true_lateral_m,true_heading_error_rad,confidence,evidence,belief_arc,"
         "position_on_arc,lateral_sigma_m,frame_lateral_m,frame_lateral_sigma_m,heading_sigma_rad,steered_lateral_m,"
         "steered_heading_error_rad,path_curvature,heading_per_lateral\n";
  PlotSeries driven, lost, path;
  driven.label = "driven (tracking)";
  driven.style = PlotSeries::Style::kPoints;
  driven.color = cv::Scalar(40, 150, 40);
  lost.label = "driven (lost / relocalizing)";
  lost.style = PlotSeries::Style::kPoints;
  lost.color = cv::Scalar(40, 40, 220);
  path.label = "taught camera path";
  path.color = cv::Scalar(150, 150, 150);
  path.thickness = 3;
  for (const TimedPose& pose : taught) {
    path.x.push_back(pose.world_from_cam.translation.x());
    path.y.push_back(pose.world_from_cam.translation.z());
  }
  PlotSeries deviation;
  deviation.label = "distance from the taught path";
  // The offset from the taught path: the truth, each frame's own estimate and the one the path law steered by.
  OffsetPlotSeries offsets = MakeOffsetPlotSeries("steered_lateral_m (what the path law steered by)");
  PlotSeries &true_offset = offsets.truth, &own_offset = offsets.own, &steered_offset = offsets.combined;

  ClosedLoopSummary summary;
  {
    ProgressBar progress("drive", 0, !args.quiet);
    summary = DriveClosedLoop(&simulator, &localizer, localizer.map(), taught, drive, [&](const ClosedLoopStep& step) {
      const FrameResult& r = *step.result;
      const Vector3d& c = step.view->world_from_cam.translation;
      const Vector3d forward = step.view->world_from_cam.rotation.col(2);
      // A value with `digits` decimals, empty when not finite (a column the frame has no value for).
      const auto number = [](double v, int digits = 3) {
        return std::isfinite(v) ? fmt::format("{:.{}f}", v, digits) : std::string();
      };
      // A value of the frame's metric path, NaN (an empty column) when it has none.
      const auto on_path = [&r](double v) { return r.path.valid ? v : std::numeric_limits<double>::quiet_NaN(); };
      csv << fmt::format("{},{:.3f},{:.3f},{:.3f},{:.4f},{},{},{},{:.5f},{:.5f},{},{},{:.2f}", r.frame_index,
                         step.view->timestamp, c.x(), c.z(), std::atan2(forward.x(), forward.z()),
                         LocalizerStateName(r.state), r.arc, r.tracked, r.steering_valid ? r.steering : 0.0,
                         step.wheels, number(step.deviation), number(step.along), 1000.0 * r.seconds)
          << fmt::format(",{},{:.5f},{:.3f},{},{},{},{}", SteeringModeName(step.command.mode), step.command.curvature,
                         step.command.speed, r.path.valid ? number(r.path.lateral_m) : "",
                         r.path.valid ? number(r.path.heading_error_rad) : "", number(step.true_lateral),
                         number(step.true_heading_error))
          << fmt::format(",{:.5f},{:d},{},{}", r.confidence, r.evidence, r.belief_arc,
                         r.position_valid ? number(r.position_on_arc) : "")
          << fmt::format(",{},{},{},{},{},{},{}", number(on_path(r.path.lateral_sigma_m)),
                         number(on_path(r.path.frame_lateral_m)), number(on_path(r.path.frame_lateral_sigma_m)),
                         number(on_path(r.path.heading_sigma_rad), 4), number(step.command.lateral_m),
                         number(step.command.heading_error_rad, 4), number(on_path(r.path.curvature), 5))
          << fmt::format(",{}\n", number(on_path(r.path.heading_per_lateral), 5));
      PlotSeries& where = r.state == LocalizerState::kTracking ? driven : lost;
      where.x.push_back(c.x());
      where.y.push_back(c.z());
      const double frame = static_cast<double>(r.frame_index);
      if (std::isfinite(step.deviation)) {
        deviation.x.push_back(frame);
        deviation.y.push_back(step.deviation);
      }
      if (std::isfinite(step.true_lateral)) {
        true_offset.x.push_back(frame);
        true_offset.y.push_back(step.true_lateral);
      }
      if (r.path.valid) {
        own_offset.x.push_back(frame);
        own_offset.y.push_back(r.path.frame_lateral_m);
      }
      if (std::isfinite(step.command.lateral_m)) {
        steered_offset.x.push_back(frame);
        steered_offset.y.push_back(step.command.lateral_m);
      }
      progress.Advance(1, r.state == LocalizerState::kTracking ? fmt::format("arc {}", r.arc)
                                                               : std::string(LocalizerStateName(r.state)));
    });
  }
  csv.flush();
  if (!csv) throw InputError(csv_path.string(), "write failed");

  std::vector<PlotSeries> top_view;
  if (!path.x.empty()) top_view.push_back(path);
  if (!driven.x.empty()) top_view.push_back(driven);
  if (!lost.x.empty()) top_view.push_back(lost);
  PlotOptions top;
  top.title = "closed loop: the car steered by retrace (seen from above)";
  top.x_label = "x (m)";
  top.y_label = "z (m)";
  top.equal_aspect = true;
  top.height = 700;
  const std::filesystem::path top_path = std::filesystem::path(args.out) / "path.png";
  if (!cv::imwrite(top_path.string(), RenderPlot(top_view, top))) {
    throw InputError(top_path.string(), "cannot be written");
  }
  std::cout << fmt::format("drive ({}): {} frames, {} tracking, {} steered by the metric path, {} standing still; {}\n",
                           args.control, summary.frames, summary.tracking, summary.path_frames,
                           summary.stopped_frames,
                           summary.reached_end ? "reached the end of the taught route"
                           : summary.stalled   ? "stood still too long (lost)"
                           : summary.left_path ? fmt::format("left the taught path (> {} m)", drive.max_deviation)
                           : summary.left_route
                               ? fmt::format("left the simulated route (past its end or > {} m off it)",
                                             Simulator::kMaxDistanceFromRoute)
                                               : "stopped before the end of the taught route");
  if (!deviation.x.empty()) {
    PlotOptions options;
    options.title = "closed loop: distance of the camera from the taught camera path";
    options.x_label = "frame";
    options.y_label = "metres";
    options.y_min = 0.0;
    const std::filesystem::path plot_path = std::filesystem::path(args.out) / "deviation.png";
    if (!cv::imwrite(plot_path.string(), RenderPlot({deviation}, options))) {
      throw InputError(plot_path.string(), "cannot be written");
    }
    std::cout << fmt::format("distance from the taught path: median {:.2f} m, max {:.2f} m\n",
                             summary.MedianDeviation(), summary.MaxDeviation());
    const PathTrackingFigures figures = summary.Figures(10.0);
    if (figures.frames > 0) {
      std::cout << fmt::format("after the first 10 m: {} frames, lateral deviation RMS {:.3f} m, 95th percentile {:.3f} "
                               "m, max {:.3f} m\n",
                               figures.frames, figures.rms, figures.p95, figures.max);
    }
  }
  const bool any_offset = !own_offset.x.empty() || !steered_offset.x.empty();
  if (any_offset) {
    PlotOptions options;
    options.title = "closed loop: offset from the taught path, true and estimated (positive: right)";
    options.x_label = "frame";
    options.y_label = "lateral offset (m)";
    std::vector<PlotSeries> series;
    for (const PlotSeries* s : {&true_offset, &own_offset, &steered_offset}) {
      if (!s->x.empty()) series.push_back(*s);
    }
    const std::filesystem::path plot_path = std::filesystem::path(args.out) / "lateral.png";
    if (!cv::imwrite(plot_path.string(), RenderPlot(series, options))) {
      throw InputError(plot_path.string(), "cannot be written");
    }
  }
  std::cout << "wrote " << csv_path.string() << ", " << top_path.string()
            << (deviation.x.empty() ? "" : ", deviation.png") << (any_offset ? ", lateral.png" : "") << "\n";
}


struct NavigateArguments {
  ScenarioArguments scenario;
  std::string map;
  int64_t goal = -1;
  std::string out;
  std::vector<std::string> taught;  // the teach sequences of the map's routes, in route order
  std::string graph = "auto";
  std::string cost = "appearance";
  bool quiet = false;
  NavigatorOptions navigator;
  NavigationLoopOptions loop;
};

void RunNavigate(const CLI::App& command, const NavigateArguments& args) {
  const Scenario scenario = ReadScenarioWithOverrides(args.scenario.scenario, args.scenario.Overrides(command));
  std::string error;
  // The options first: a bad one is the command line's fault, not the map's.
  if (!args.navigator.Check(&error)) throw InputError("sim navigate options", error);
  // Key-images read on demand, and the tracking settings teach stored (the localizer beneath the navigator).
  MapForLocalizer loaded = LoadMapForLocalizer(args.map, args.navigator.localizer);
  Map& map = loaded.map;
  const node_t goal = static_cast<node_t>(args.goal);
  if (args.goal < 0 || map.FindNode(goal) == nullptr) {
    throw InputError(args.map, fmt::format("has no key-image {} (--goal; `retrace inspect --json` lists them)", args.goal));
  }
  std::unordered_map<node_t, Vector2d> truth;
  if (!args.taught.empty()) {
    const KeyImagePlaces places = ReadKeyImagePlaces(map, {args.taught.begin(), args.taught.end()});
    if (!places.town_frame) {
      throw InputError(args.taught.front(), "--taught needs the simulator's teach sequences (their scenario.yaml)");
    }
    truth = places.positions;
  }

  Simulator simulator(ApplyVariant(scenario, ScenarioVariant::kRepeat));
  const CameraModel& camera = simulator.camera();
  const cv::Mat any_key_image = map.KeyImage(map.nodes().front().id);
  if (any_key_image.cols != camera.width() || any_key_image.rows != camera.height()) {
    throw InputError(args.map, fmt::format("key-images are {}x{} but the scenario's camera is {}x{} (--width, --height)",
                                           any_key_image.cols, any_key_image.rows, camera.width(), camera.height()));
  }
  NavigatorOptions options = args.navigator;
  options.localizer = loaded.options;
  options.planning.cost = args.cost == "drive" ? PlanOptions::Cost::kDrive : PlanOptions::Cost::kAppearance;
  // An omnidirectional camera sees a route backwards too (the paper's undirected graph); a perspective one only
  // ahead.
  options.planning.directed = args.graph == "directed" ||
                              (args.graph == "auto" && camera.type() == CameraModelType::kPerspective);
  if (!options.Check(&error)) throw InputError("sim navigate options", error);
  NavigationLoopOptions loop = args.loop;
  loop.frame_period = 1.0 / scenario.frame_rate;
  if (!loop.Check(&error)) throw InputError("sim navigate options", error);
  Navigator navigator(std::move(map), camera, goal, options);
  if (navigator.distances_to_goal().size() <= 1) {
    throw InputError(args.map, fmt::format("no key-image can reach the goal {} ({} graph)", goal,
                                           options.planning.directed ? "directed" : "undirected"));
  }

  std::filesystem::create_directories(args.out);
  const std::filesystem::path out(args.out);
  const std::filesystem::path csv_path = out / "drive.csv";
  std::ofstream csv(csv_path);
  if (!csv) throw InputError(csv_path.string(), "cannot be written");
  csv << "frame,timestamp,x,y,yaw,state,subgoal,advanced,compared,relocalized,heading,filtered_heading,similarity,"
         "misses,curvature,speed,wheels,ms,true_heading,along_arc,localizer,arc,on_plan,image_steering,replanned\n";
  const auto number = [](std::optional<double> v) { return v ? fmt::format("{:.4f}", *v) : std::string(); };
  NavigationLoopSummary summary;
  std::vector<Vector2d> image_steered, replanned;  // where the car steered by eq. (10), where it replanned
  {
    ProgressBar progress("navigate", 0, !args.quiet);
    int frame = 0;
    summary = DriveToGoal(&simulator, &navigator, loop, truth, [&](const NavigationLoopStep& s) {
      const NavigationStep& n = *s.step;
      const Vector2d position = s.view->town_from_cam.translation.head<2>();
      if (n.image_steering) image_steered.push_back(position);
      if (n.replanned) replanned.push_back(position);
      const Rigid3d& town_from_cam = s.view->town_from_cam;
      const Vector3d forward = town_from_cam.rotation.col(2);
      // The true heading to the subgoal, as the navigator measures it (0 ahead, positive right).
      std::optional<double> true_heading;
      if (const auto t = truth.find(n.subgoal); t != truth.end()) {
        const Vector3d to_subgoal(t->second.x() - town_from_cam.translation.x(),
                                  t->second.y() - town_from_cam.translation.y(), 0.0);
        const Vector3d in_cam = town_from_cam.rotation.transpose() * to_subgoal;
        true_heading = std::atan2(in_cam.x(), in_cam.z());
      }
      csv << fmt::format("{},{:.3f},{:.3f},{:.3f},{:.4f},{},{},{},{},{},", frame++, s.view->timestamp,
                         town_from_cam.translation.x(), town_from_cam.translation.y(),
                         std::atan2(forward.y(), forward.x()), NavigationStateName(n.state),
                         n.subgoal == kInvalidNodeId ? std::string() : std::to_string(n.subgoal), n.advanced,
                         n.compared, n.relocalized ? 1 : 0)
          << fmt::format("{},{},{:.4f},{},{:.5f},{:.3f},{:.5f},{:.1f},{},{},", number(n.heading),
                         number(n.filtered_heading), n.similarity, n.misses, n.curvature, n.speed, s.wheels,
                         1000.0 * n.seconds, number(true_heading), n.along_arc ? 1 : 0)
          << fmt::format("{},{},{},{},{}\n", LocalizerStateName(n.localizer_state),
                         n.arc == kInvalidArcId ? std::string() : std::to_string(n.arc), n.on_plan ? 1 : 0,
                         n.image_steering ? 1 : 0, n.replanned ? 1 : 0);
      progress.Advance(1, n.subgoal == kInvalidNodeId ? std::string(NavigationStateName(n.state))
                                                      : fmt::format("subgoal {}", n.subgoal));
    });
  }
  csv.flush();
  if (!csv) throw InputError(csv_path.string(), "write failed");

  // Ground-truth figures: distance to the goal's key-image and the street distance (the grid's streets: the
  // Manhattan distance between start and goal, exact where they lie on crossing streets).
  nlohmann::json json{{"reached_goal", summary.reached_goal},
                      {"frames", summary.frames},
                      {"path_length_m", summary.path_length_m},
                      {"relocalizations", summary.relocalizations},
                      {"frames_without_heading", summary.frames_without_heading},
                      {"image_steering_frames", summary.image_steering_frames},
                      {"replans", summary.replans},
                      {"stalled", summary.stalled},
                      {"left_streets", summary.left_streets},
                      {"planned_path", navigator.planned_path().nodes}};
  std::string figures;
  if (!truth.empty() && !summary.camera_positions.empty()) {
    const Vector2d goal_position = truth.at(goal);
    const Vector2d d = summary.camera_positions.back() - goal_position;
    const Vector2d s = summary.camera_positions.front() - goal_position;
    json["distance_to_goal_m"] = d.norm();
    json["max_off_path_m"] = summary.max_off_plan_m;
    json["mean_off_path_m"] = summary.mean_off_plan_m;
    json["street_distance_m"] = std::abs(s.x()) + std::abs(s.y());
    json["length_ratio"] = summary.path_length_m / std::max(1e-9, json["street_distance_m"].get<double>());
    figures = fmt::format("; {:.2f} m from the goal, driven {:.1f} m for a street distance of {:.1f} m ({:+.1f} %), "
                          "at most {:.1f} m from the planned path",
                          d.norm(), summary.path_length_m, json["street_distance_m"].get<double>(),
                          100.0 * (json["length_ratio"].get<double>() - 1.0), summary.max_off_plan_m);
  }
  const std::filesystem::path json_path = out / "summary.json";
  {
    std::ofstream file(json_path);
    file << json.dump(2) << "\n";
    if (!file) throw InputError(json_path.string(), "cannot be written");
  }

  // From above: the graph's key-images (ground truth), the planned path, the driven path.
  std::vector<PlotSeries> top_view;
  if (!truth.empty()) {
    std::map<int, PlotSeries> routes;
    for (const MapNode& node : navigator.map().nodes()) {
      PlotSeries& r = routes[node.route];
      r.label = fmt::format("key-images of route {}", node.route);
      r.style = PlotSeries::Style::kPoints;
      r.color = SeriesColor(node.route + 2);
      r.x.push_back(truth.at(node.id).x());
      r.y.push_back(truth.at(node.id).y());
    }
    for (auto& entry : routes) top_view.push_back(entry.second);
    PlotSeries planned;
    planned.label = "planned path (from the last localization)";
    planned.color = cv::Scalar(200, 60, 170);  // violet: the routes' key-images take the series colours
    planned.thickness = 3;
    for (node_t n : navigator.planned_path().nodes) {
      planned.x.push_back(truth.at(n).x());
      planned.y.push_back(truth.at(n).y());
    }
    if (!planned.x.empty()) top_view.push_back(planned);
    PlotSeries goal_point;
    goal_point.label = "goal";
    goal_point.style = PlotSeries::Style::kPoints;
    goal_point.thickness = 8;
    goal_point.color = cv::Scalar(0, 160, 255);
    goal_point.x.push_back(truth.at(goal).x());
    goal_point.y.push_back(truth.at(goal).y());
    top_view.push_back(goal_point);
  }
  PlotSeries driven;
  driven.label = "driven by retrace";
  driven.color = cv::Scalar(30, 30, 30);
  for (const Vector2d& p : summary.camera_positions) {
    driven.x.push_back(p.x());
    driven.y.push_back(p.y());
  }
  top_view.push_back(driven);
  const auto points = [](const std::vector<Vector2d>& positions, const std::string& label, cv::Scalar color,
                         int thickness) {
    PlotSeries series;
    series.label = label;
    series.style = PlotSeries::Style::kPoints;
    series.color = color;
    series.thickness = thickness;
    for (const Vector2d& p : positions) {
      series.x.push_back(p.x());
      series.y.push_back(p.y());
    }
    return series;
  };
  if (!image_steered.empty()) {
    top_view.push_back(points(image_steered, "steered by the image (eq. (10), on a taught arc of the plan)",
                              cv::Scalar(230, 160, 0), 2));
  }
  if (!replanned.empty()) top_view.push_back(points(replanned, "replanned (off the plan)", cv::Scalar(0, 0, 220), 8));
  PlotOptions top;
  top.title = "navigation to a goal (seen from above, town frame)";
  top.x_label = "east (m)";
  top.y_label = "north (m)";
  top.equal_aspect = true;
  top.height = 800;
  const std::filesystem::path top_path = out / "path.png";
  if (!cv::imwrite(top_path.string(), RenderPlot(top_view, top))) throw InputError(top_path.string(), "cannot be written");

  std::cout << fmt::format("navigate to key-image {}: {} after {} frames, {} relocalizations, {} frames without a "
                           "heading{}\n",
                           goal,
                           summary.reached_goal ? "stopped at the goal"
                           : summary.stalled    ? "gave up standing still (not localized)"
                           : summary.left_streets ? "left the streets"
                                                  : "did not reach the goal in --max-frames",
                           summary.frames, summary.relocalizations, summary.frames_without_heading, figures);
  std::cout << "wrote " << csv_path.string() << ", " << top_path.string() << ", " << json_path.string() << "\n";
}

}  // namespace

void RegisterSimCommand(CLI::App& app) {
  CLI::App* sim = app.add_subcommand("sim", "Simulator: render drives through a procedural town with ground truth");
  sim->require_subcommand(1);

  CLI::App* example = sim->add_subcommand("example-scenario", "Print a documented default scenario (YAML)");
  example->callback([]() { std::cout << ScenarioToYaml(Scenario()); });

  CLI::App* render = sim->add_subcommand(
      "render",
      "Render a drive into a KITTI-layout sequence (image_0/, times.txt, poses.txt, calib.txt) or a ROS bag (--bag)");
  auto render_args = std::make_shared<RenderArguments>();
  const Scenario defaults;
  render_args->scenario.Register(render);
  CLI::Option* out = render->add_option("--out", render_args->out, "Output folder of the sequence");
  render->add_option("--bag", render_args->bag,
                     "Write the drive as a ROS bag instead: /camera/image_raw, /camera/camera_info, "
                     "/ground_truth/pose (geometry_msgs/PoseStamped, world_from_cam)")
      ->excludes(out);
  render->add_option("--variant", render_args->variant,
                     "teach, or repeat (other sun and exposure, 1 m lateral offset, wobble)")
      ->check(CLI::IsMember({"teach", "repeat"}));
  render->add_option("--frames", render_args->frames,
                     "Number of frames, " + RangeOf("frames") + " (0 = the whole route; the drive stops at the "
                         "route's end either way and says so); overrides the scenario");
  render->add_option("--speed", render_args->speed,
                     fmt::format("Top speed on straight streets (slower in turns), {}; default {}",
                                 RangeOf("drive.max_speed"), defaults.drive.max_speed));
  render->add_option("--contact-sheet", render_args->contact_sheet, "Also write a PNG with every Nth frame");
  render->add_option("--contact-sheet-every", render_args->sheet_every,
                     fmt::format("N for --contact-sheet, 1..{} (default 10)", MaxFrames()));
  render->add_flag("--quiet", render_args->quiet, "No progress bar");
  render->add_option("--poses", render_args->poses,
                     "Render at these camera poses instead of driving: KITTI poses.txt (world_from_cam, 3x4 per line) "
                     "in the simulator's world frame (x right, y down, z forward of the camera at the route's start)");
  render->callback([render, render_args]() {
    if (render_args->out.empty() && render_args->bag.empty()) {
      throw InputError("", "sim render: give --out FOLDER or --bag FILE");
    }
    if (!render_args->poses.empty() && (!render_args->bag.empty() || render_args->out.empty())) {
      throw InputError(render_args->poses, "sim render --poses writes a folder: give --out FOLDER (not --bag)");
    }
    if (!render_args->bag.empty() && !render_args->contact_sheet.empty()) {
      throw InputError("", "sim render: --contact-sheet is written with --out only");
    }
    RunRender(*render, *render_args);
  });

  CLI::App* drive = sim->add_subcommand(
      "drive", "Drive the scenario's repeat variant with retrace's steering in a taught map (closed loop)");
  auto args = std::make_shared<DriveArguments>();
  args->scenario.Register(drive);
  drive->add_option("--map", args->map, "Map taught on the scenario's teach drive (`retrace teach`, the same --width, "
                    "--height, --seed, --route ...)")->required();
  drive->add_option("--out", args->out, "Output folder: drive.csv, path.png (and deviation.png, lateral.png)")
      ->required();
  drive->add_option("--taught-poses", args->taught_poses,
                    "Ground-truth poses of the teach drive (its poses.txt): distance from the taught path per frame");
  drive->add_option("--control", args->control,
                    "Steering law: path (the camera-point law on the metric offset from the taught path, eq. (10) "
                    "where there is none) or eq10 (Segvic 2009 eq. (10) alone)")
      ->check(CLI::IsMember({"path", "eq10"}))
      ->capture_default_str();
  drive->add_option("--speed", args->drive.tracking.max_speed, "Top speed, (0, 50] m/s (slower in turns, 0 when lost)")
      ->capture_default_str();
  drive->add_option("--camera-height", args->camera_height,
                    "Camera height above the ground (m) for the metric path; default: the scenario's vehicle");
  drive->add_option("--camera-forward", args->camera_forward,
                    "Camera distance ahead of the rear axle (m); default: the scenario's vehicle");
  drive->add_option("--approach-distance", args->drive.tracking.approach_distance,
                    "Distance over which the path law closes a lateral offset (m)")
      ->capture_default_str();
  drive->add_flag(
      "--affine-refine,!--no-affine-refine", args->affine_refine,
      "Localizer: refine every tracked feature with an affine warp (`repeat --affine-refine`; on by default)");
  drive->add_flag("--verified-placement,!--no-verified-placement", args->verified_placement,
                  "Localizer: place the camera by the key-images a relocalization verified when too few mapped "
                  "features align through them (`repeat --verified-placement`; on by default)");
  drive->add_flag("--multi-view-points,!--no-multi-view-points", args->multi_view_points,
                  "Localizer: triangulate each arc's points again from every key-image that sees them (`repeat "
                  "--multi-view-points`; on by default)");
  drive->add_flag("--relocalization-affine", args->relocalization_affine,
                  "Localizer: align the mapped features a relocalization locates with the affine fallback (`repeat "
                  "--relocalization-affine`)");
  drive->add_option("--travel-window", args->travel_window,
                    "Localizer: arcs before and after the current one whose turns fit the vehicle's travel model, "
                    "the heading error's reference (`repeat --travel-window`; 0: the arcs' chords)")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  drive->add_flag("--robust-relocalization", args->robust_relocalization,
                  "Localizer: after a loss, align the mapped features a relocalization cannot locate otherwise with "
                  "the robust fallback (`repeat --robust-relocalization`)");
  drive
      ->add_option("--start-alternative-starts", args->start_alternative_starts,
                   "Localizer: before its first localization, align a mapped feature that fails from the median of the "
                   "matches around it from each of this many nearest matches (`repeat --start-alternative-starts`; "
                   "0: the median alone)")
      ->check(CLI::Range(0, 100))
      ->capture_default_str();
  drive->add_flag("--placed-start-fine,!--no-placed-start-fine", args->placed_start_fine,
                  "Localizer: track the mapped features it placed from a fine pyramid level in every frame (`repeat "
                  "--placed-start-fine`; on by default)");
  drive
      ->add_option("--guided-matching", args->guided_matching,
                   "Localizer: near a loss or the start, verify a key-image by matching it again along the epipolar "
                   "planes of a relative pose with at least this many inliers (`repeat --guided-matching`; 0: off)")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  drive
      ->add_option("--offset-shared-correlation", args->drive.tracking.offset.shared_correlation,
                   "Path law: correlation in [0, 1) of the offset errors of two frames whose poses are in one arc's "
                   "reconstruction, when the recent frames' offsets are combined (0: independent)")
      ->check(CLI::Range(0.0, 0.999))
      ->capture_default_str();
  drive->add_flag("--heading-from-offset", args->drive.tracking.heading_from_offset,
                  "Path law: steer by the heading that goes with the recent frames' combined offset (the pose's "
                  "heading-offset covariance) instead of the frame's own");
  drive
      ->add_option("--heading-process-sigma", args->drive.tracking.heading_process_sigma,
                   "Path law: the heading steered by is the frame's own combined with the last frame's carried by the "
                   "commanded motion and the taught path's curvature, plus a random walk of this many rad/sqrt(m) "
                   "(a one-state Kalman filter; 0: each frame's own heading)")
      ->check(CLI::Range(0.0, 10.0))
      ->capture_default_str();
  drive->add_option("--image-gain", args->drive.tracking.image_gain,
                    "eq. (10) law: curvature = -gain * w (1/m), [-100, 100]")
      ->capture_default_str();
  drive->add_option("--blackout", args->drive.blackout_start, "First frame of a covered lens (with --blackout-frames)");
  drive->add_option("--blackout-frames", args->drive.blackout_frames,
                    "Frames replaced by a black image: the car must stop and resume")
      ->capture_default_str();
  drive->add_option("--max-frames", args->drive.max_frames,
                    "Stop after this many frames, 1..1000000 (the drive also stops where the simulated route "
                    "ends or more than 20 m off it)")
      ->capture_default_str();
  drive->add_option("--max-deviation", args->drive.max_deviation,
                    "Stop when farther than this from the taught path, (0, 1000] m (with --taught-poses)")
      ->capture_default_str();
  drive->add_option("--start-arc", args->start_arc,
                    "Arc the repeat starts on (default: the first arc of the taught route, where the scenario's "
                    "repeat starts)");
  drive->add_flag("--no-start-arc", args->no_start_arc,
                  "Find the start by retrieval over the whole map instead (a robot put down anywhere)");
  drive->add_flag("--quiet", args->quiet, "No progress bar");
  drive->callback([drive, args]() { RunDrive(*drive, *args); });

  CLI::App* navigate = sim->add_subcommand(
      "navigate", "Drive the car from the scenario's start to a goal key-image of a map of several routes with "
                  "retrace's navigator (closed loop, Booij 2007): drive.csv, path.png, summary.json");
  auto nav_args = std::make_shared<NavigateArguments>();
  nav_args->scenario.Register(navigate);
  navigate->add_option("--map", nav_args->map, "Map of the town's routes (`retrace teach`, `teach --append`)")->required();
  navigate->add_option("--goal", nav_args->goal, "Goal key-image (node id, as in `retrace inspect --json`)")->required();
  navigate->add_option("--out", nav_args->out, "Output folder: drive.csv, path.png, summary.json")->required();
  navigate->add_option("--taught", nav_args->taught,
                       "The recorded teach sequences of the map's routes, in route order (their scenario.yaml and "
                       "poses.txt): ground truth for the distance to the goal and the drawing");
  navigate->add_option("--graph", nav_args->graph,
                       "Plan along the taught directions (directed) or both ways (undirected); auto: undirected for "
                       "a panoramic camera, directed otherwise")
      ->check(CLI::IsMember({"auto", "directed", "undirected"}))
      ->capture_default_str();
  navigate->add_option("--cost", nav_args->cost, "Edge length: appearance (1 / S, Booij 2007) or drive (teach seconds)")
      ->check(CLI::IsMember({"appearance", "drive"}))
      ->capture_default_str();
  navigate->add_option("--speed", nav_args->navigator.speed, "Speed while a heading is known, (0, 50] m/s")
      ->capture_default_str();
  navigate->add_option("--look-ahead", nav_args->navigator.look_ahead,
                       "Pure-pursuit distance towards the subgoal's heading, m")
      ->capture_default_str();
  navigate->add_option("--localization-candidates", nav_args->navigator.localization_candidates,
                       "Key-images compared when (re)localizing: 0 = all (the paper), else the closest in appearance")
      ->capture_default_str();
  navigate->add_option("--match-ratio", nav_args->navigator.matching.ratio,
                       "Ratio test of the wide-baseline matches between the image and a key-image")
      ->capture_default_str();
  navigate->add_option("--min-similarity", nav_args->navigator.min_similarity,
                       "Similarity S at which a key-image matches the image (Booij 2007: 0.05)")
      ->capture_default_str();
  navigate->add_flag("--heading-only{false}", nav_args->navigator.follow_taught_arcs,
                     "Steer by the heading alone (Booij 2007), without the Segvic localizer beneath: no image "
                     "steering on the plan's taught arcs, no replanning off the plan");
  navigate->add_option("--planned-branch-probability", nav_args->navigator.localizer.belief.planned_branch_probability,
                       "At a junction, the probability the localizer's belief gives the plan's branch, (0, 1); 0.5 of "
                       "two branches: no preference")
      ->capture_default_str();
  navigate->add_option("--max-frames", nav_args->loop.max_frames, "Give up after this many frames")->capture_default_str();
  navigate->add_flag("--quiet", nav_args->quiet, "No progress bar");
  navigate->callback([navigate, nav_args]() { RunNavigate(*navigate, *nav_args); });
}

}  // namespace retrace
