// `retrace sim ...`: the simulator. Renders drives through the built-in procedural town into KITTI-layout
// sequences (images, calibration, timestamps, ground-truth poses), and prints a documented example scenario.

#include <cmath>
#include <fstream>
#include <iostream>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <spdlog/spdlog.h>

#include "retrace/dataset/ground_truth.h"
#include "retrace/drive/closed_loop.h"
#include "retrace/exe/commands.h"
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

  std::filesystem::create_directories(args.out);
  const std::filesystem::path csv_path = std::filesystem::path(args.out) / "drive.csv";
  std::ofstream csv(csv_path);
  if (!csv) throw InputError(csv_path.string(), "cannot be written");
  csv << "frame,timestamp,x,z,heading,state,arc,tracked,steering,wheels,deviation,along,ms,mode,curvature,speed,"
         "lateral_m,heading_error_rad,true_lateral_m,true_heading_error_rad\n";
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

  ClosedLoopSummary summary;
  {
    ProgressBar progress("drive", 0, !args.quiet);
    summary = DriveClosedLoop(&simulator, &localizer, localizer.map(), taught, drive, [&](const ClosedLoopStep& step) {
      const FrameResult& r = *step.result;
      const Vector3d& c = step.view->world_from_cam.translation;
      const Vector3d forward = step.view->world_from_cam.rotation.col(2);
      const auto number = [](double v) { return std::isfinite(v) ? fmt::format("{:.3f}", v) : std::string(); };
      csv << fmt::format("{},{:.3f},{:.3f},{:.3f},{:.4f},{},{},{},{:.5f},{:.5f},{},{},{:.2f}", r.frame_index,
                         step.view->timestamp, c.x(), c.z(), std::atan2(forward.x(), forward.z()),
                         LocalizerStateName(r.state), r.arc, r.tracked, r.steering_valid ? r.steering : 0.0,
                         step.wheels, number(step.deviation), number(step.along), 1000.0 * r.seconds)
          << fmt::format(",{},{:.5f},{:.3f},{},{},{},{}\n", SteeringModeName(step.command.mode),
                         step.command.curvature, step.command.speed, r.path.valid ? number(r.path.lateral_m) : "",
                         r.path.valid ? number(r.path.heading_error_rad) : "", number(step.true_lateral),
                         number(step.true_heading_error));
      PlotSeries& where = r.state == LocalizerState::kTracking ? driven : lost;
      where.x.push_back(c.x());
      where.y.push_back(c.z());
      if (std::isfinite(step.deviation)) {
        deviation.x.push_back(static_cast<double>(r.frame_index));
        deviation.y.push_back(step.deviation);
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
  std::cout << "wrote " << csv_path.string() << ", " << top_path.string()
            << (deviation.x.empty() ? "" : ", deviation.png") << "\n";
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
  drive->add_option("--out", args->out, "Output folder: drive.csv, path.png (and deviation.png)")->required();
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
  drive->add_flag("--quiet", args->quiet, "No progress bar");
  drive->callback([drive, args]() { RunDrive(*drive, *args); });
}

}  // namespace retrace
