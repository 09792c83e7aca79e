// `retrace sim ...`: the simulator. Renders drives through the built-in procedural town into KITTI-layout
// sequences (images, calibration, timestamps, ground-truth poses), and prints a documented example scenario.

#include <iostream>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "retrace/exe/commands.h"
#include "retrace/sim/recording.h"
#include "retrace/sim/scenario_io.h"
#include "retrace/sim/simulator.h"
#include "retrace/util/error.h"

namespace retrace {

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
    if (*frames >= 0) scenario.num_frames = *frames;
    if (*width > 0) {
      if (scenario.camera.fx > 0.0) {
        const double s = static_cast<double>(*width) / scenario.camera.width;
        scenario.camera.fx *= s;
        scenario.camera.fy *= s;
        if (scenario.camera.cx >= 0) scenario.camera.cx = (scenario.camera.cx + 0.5) * s - 0.5;
        if (scenario.camera.cy >= 0) scenario.camera.cy = (scenario.camera.cy + 0.5) * s - 0.5;
      }
      scenario.camera.width = *width;
    }
    if (*height > 0) scenario.camera.height = *height;
    if (*seed >= 0) {
      scenario.seed = static_cast<uint64_t>(*seed);
      scenario.town.seed = scenario.seed;
      scenario.drive.wobble_seed = scenario.seed;
    }
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
}

}  // namespace retrace
