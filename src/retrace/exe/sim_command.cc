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
#include "retrace/sim/recording.h"
#include "retrace/sim/scenario_io.h"
#include "retrace/sim/simulator.h"
#include "retrace/util/error.h"
#include "retrace/util/progress.h"
#include "retrace/viz/plot.h"

namespace retrace {

namespace {

// Command-line overrides of a scenario shared by `sim render` and `sim drive` (negative / zero = keep).
void ApplyOverrides(int frames, int width, int height, int64_t seed, Scenario* scenario) {
  if (frames >= 0) scenario->num_frames = frames;
  if (width > 0) {
    if (scenario->camera.fx > 0.0) {
      const double s = static_cast<double>(width) / scenario->camera.width;
      scenario->camera.fx *= s;
      scenario->camera.fy *= s;
      if (scenario->camera.cx >= 0) scenario->camera.cx = (scenario->camera.cx + 0.5) * s - 0.5;
      if (scenario->camera.cy >= 0) scenario->camera.cy = (scenario->camera.cy + 0.5) * s - 0.5;
    }
    scenario->camera.width = width;
  }
  if (height > 0) scenario->camera.height = height;
  if (seed >= 0) {
    scenario->seed = static_cast<uint64_t>(seed);
    scenario->town.seed = scenario->seed;
    scenario->drive.wobble_seed = scenario->seed;
  }
}

struct DriveArguments {
  std::string scenario;
  std::string map;
  std::string out;
  std::string taught_poses;
  int width = 0;
  int height = 0;
  int64_t seed = -1;
  bool quiet = false;
  ClosedLoopOptions drive;
};

// `sim drive`: the repeat variant of the scenario driven by the localizer's steering (closed loop).
void RunDrive(const DriveArguments& args) {
  Scenario scenario = args.scenario.empty() ? Scenario() : ReadScenario(args.scenario);
  ApplyOverrides(-1, args.width, args.height, args.seed, &scenario);
  const std::string problem = scenario.Validate();
  if (!problem.empty()) throw InputError(args.scenario.empty() ? "command line" : args.scenario, problem);
  std::string error;
  if (!args.drive.Check(&error)) throw InputError("sim drive options", error);
  const std::vector<TimedPose> taught =
      args.taught_poses.empty() ? std::vector<TimedPose>() : ReadKittiPoses(args.taught_poses);

  MapForLocalizer loaded = LoadMapForLocalizer(args.map, LocalizerOptions());
  Simulator simulator(ApplyVariant(scenario, ScenarioVariant::kRepeat));
  const CameraModel& camera = simulator.camera();
  const cv::Mat& key_image = loaded.map.nodes().front().image;
  if (key_image.cols != camera.width() || key_image.rows != camera.height()) {
    throw InputError(args.map, fmt::format("key-images are {}x{} but the scenario's camera is {}x{} (--width, "
                                           "--height)",
                                           key_image.cols, key_image.rows, camera.width(), camera.height()));
  }
  Localizer localizer(loaded.map, camera, loaded.options);

  std::filesystem::create_directories(args.out);
  const std::filesystem::path csv_path = std::filesystem::path(args.out) / "drive.csv";
  std::ofstream csv(csv_path);
  if (!csv) throw InputError(csv_path.string(), "cannot be written");
  csv << "frame,timestamp,x,z,heading,state,arc,tracked,steering,wheels,deviation,along,ms\n";
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
    summary = DriveClosedLoop(&simulator, &localizer, loaded.map, taught, args.drive, [&](const ClosedLoopStep& step) {
      const FrameResult& r = *step.result;
      const Vector3d& c = step.view->world_from_cam.translation;
      const Vector3d forward = step.view->world_from_cam.rotation.col(2);
      const auto number = [](double v) { return std::isfinite(v) ? fmt::format("{:.3f}", v) : std::string(); };
      csv << fmt::format("{},{:.3f},{:.3f},{:.3f},{:.4f},{},{},{},{:.5f},{:.5f},{},{},{:.2f}\n", r.frame_index,
                         step.view->timestamp, c.x(), c.z(), std::atan2(forward.x(), forward.z()),
                         LocalizerStateName(r.state), r.arc, r.tracked, r.steering_valid ? r.steering : 0.0,
                         step.wheels, number(step.deviation), number(step.along), 1000.0 * r.seconds);
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
  std::cout << fmt::format("drive: {} frames, {} tracking; {}\n", summary.frames, summary.tracking,
                           summary.reached_end ? "reached the end of the taught route"
                           : summary.left_path ? fmt::format("left the taught path (> {} m)", args.drive.max_deviation)
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
      "render", "Render a drive into a KITTI-layout sequence (image_0/, times.txt, poses.txt, calib.txt)");
  auto scenario_path = std::make_shared<std::string>();
  auto out_dir = std::make_shared<std::string>();
  auto variant = std::make_shared<std::string>("teach");
  auto frames = std::make_shared<int>(-1);
  auto width = std::make_shared<int>(0);
  auto height = std::make_shared<int>(0);
  auto seed = std::make_shared<int64_t>(-1);
  auto threads = std::make_shared<int>(0);
  auto contact_sheet = std::make_shared<std::string>();
  auto sheet_every = std::make_shared<int>(10);
  auto quiet = std::make_shared<bool>(false);
  render->add_option("--scenario", *scenario_path, "Scenario file (YAML/JSON); default: the built-in scenario");
  render->add_option("--out", *out_dir, "Output folder of the sequence")->required();
  render->add_option("--variant", *variant, "teach, or repeat (other sun and exposure, 1 m lateral offset, wobble)")
      ->check(CLI::IsMember({"teach", "repeat"}));
  render->add_option("--frames", *frames, "Number of frames (0 = whole route); overrides the scenario");
  render->add_option("--width", *width, "Image width; overrides the scenario (keeps the field of view)");
  render->add_option("--height", *height, "Image height; overrides the scenario");
  render->add_option("--seed", *seed, "Seed of the drive and the town; overrides the scenario");
  render->add_option("--threads", *threads, "Render threads; overrides the scenario");
  render->add_option("--contact-sheet", *contact_sheet, "Also write a PNG with every Nth frame");
  render->add_option("--contact-sheet-every", *sheet_every, "N for --contact-sheet (default 10)");
  render->add_flag("--quiet", *quiet, "No progress bar");
  render->callback([=]() {
    Scenario scenario = scenario_path->empty() ? Scenario() : ReadScenario(*scenario_path);
    const std::string source = scenario_path->empty() ? "command line" : *scenario_path;
    ApplyOverrides(*frames, *width, *height, *seed, &scenario);
    if (*threads > 0) scenario.render.num_threads = *threads;
    const std::string problem = scenario.Validate();
    if (!problem.empty()) throw InputError(source, problem);
    const ScenarioVariant v = *variant == "repeat" ? ScenarioVariant::kRepeat : ScenarioVariant::kTeach;
    Simulator simulator(ApplyVariant(scenario, v));
    RecordOptions options;
    options.progress = !*quiet;
    options.contact_sheet = *contact_sheet;
    options.contact_sheet_every = std::max(1, *sheet_every);
    const RecordSummary summary = RecordSequence(&simulator, *out_dir, options);
    std::cout << fmt::format("wrote {} frames ({:.0f} m of a {:.0f} m route, {} variant) to {} in {:.1f} s ({:.1f} fps)\n",
                             summary.frames, summary.driven_m, summary.route_length_m, *variant, *out_dir,
                             summary.seconds, summary.frames / std::max(1e-9, summary.seconds));
    if (!contact_sheet->empty()) std::cout << "contact sheet: " << *contact_sheet << "\n";
  });

  CLI::App* drive = sim->add_subcommand(
      "drive", "Drive the scenario's repeat variant with retrace's steering in a taught map (closed loop)");
  auto args = std::make_shared<DriveArguments>();
  drive->add_option("--scenario", args->scenario, "Scenario file (YAML/JSON); default: the built-in scenario");
  drive->add_option("--map", args->map, "Map taught on the scenario's teach drive (`retrace teach`)")->required();
  drive->add_option("--out", args->out, "Output folder: drive.csv, path.png (and deviation.png)")->required();
  drive->add_option("--taught-poses", args->taught_poses,
                    "Ground-truth poses of the teach drive (its poses.txt): distance from the taught path per frame");
  drive->add_option("--width", args->width, "Image width; overrides the scenario (must match the map)");
  drive->add_option("--height", args->height, "Image height; overrides the scenario");
  drive->add_option("--seed", args->seed, "Seed of the drive and the town; overrides the scenario");
  drive->add_option("--speed", args->drive.speed, "Constant speed, m/s")->capture_default_str();
  drive->add_option("--steering-gain", args->drive.steering_gain, "Front wheels = -gain * w of eq. (10)")
      ->capture_default_str();
  drive->add_option("--max-frames", args->drive.max_frames, "Stop after this many frames")->capture_default_str();
  drive->add_option("--max-deviation", args->drive.max_deviation,
                    "Stop when farther than this from the taught path, metres (with --taught-poses)")
      ->capture_default_str();
  drive->add_flag("--quiet", args->quiet, "No progress bar");
  drive->callback([args]() { RunDrive(*args); });
}

}  // namespace retrace
