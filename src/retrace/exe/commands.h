#pragma once

// Every subcommand of the `retrace` binary registers itself here: a function that adds a CLI11 subcommand to the
// app and sets its callback. The callback throws retrace::InputError on bad input; main() turns that into a
// one-line message and exit code 1.

#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>

#include "retrace/camera/camera_model.h"
#include "retrace/map/map.h"
#include "retrace/repeat/localizer.h"
#include "retrace/repeat/map_loading.h"

namespace retrace {

void RegisterVersionCommand(CLI::App& app);
void RegisterSequenceInfoCommand(CLI::App& app);
void RegisterPerturbCommand(CLI::App& app);
void RegisterInspectCommand(CLI::App& app);
void RegisterTeachCommand(CLI::App& app);
void RegisterCalibrateCommand(CLI::App& app);
void RegisterCameraInfoCommand(CLI::App& app);
void RegisterTwoViewCommand(CLI::App& app);
void RegisterSimCommand(CLI::App& app);
void RegisterRepeatCommand(CLI::App& app);
void RegisterBenchCommand(CLI::App& app);
void RegisterBenchHeadingCommand(CLI::App* bench);  // `bench heading`, added by RegisterBenchCommand
void RegisterPlanCommand(CLI::App& app);

}  // namespace retrace
