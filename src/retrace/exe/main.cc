// The `retrace` command-line tool: one binary, one subcommand per job (see `retrace --help`).

#include <algorithm>
#include <iostream>
#include <string>

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include "retrace/exe/commands.h"
#include "retrace/util/error.h"
#include "retrace/util/error_message.h"
#include "retrace/util/version.h"

namespace {

// The table of subcommands, in the order `retrace --help` lists them.
constexpr void (*kCommands[])(CLI::App&) = {
    &retrace::RegisterVersionCommand,
    &retrace::RegisterSequenceInfoCommand,
    &retrace::RegisterPerturbCommand,
    &retrace::RegisterTeachCommand,
    &retrace::RegisterInspectCommand,
    &retrace::RegisterCalibrateCommand,
    &retrace::RegisterCameraInfoCommand,
    &retrace::RegisterTwoViewCommand,
    &retrace::RegisterSimCommand,
    &retrace::RegisterRepeatCommand,
    &retrace::RegisterBenchCommand,
    &retrace::RegisterPlanCommand,
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"retrace: monocular visual teach-and-repeat navigation"};
  app.require_subcommand(1);
  bool verbose = false;
  app.add_flag("-v,--verbose", verbose, "Print debug messages");
  app.set_version_flag("--version", std::string("retrace ") + retrace::Version());
  for (auto* register_command : kCommands) register_command(app);
  app.parse_complete_callback([&]() { spdlog::set_level(verbose ? spdlog::level::debug : spdlog::level::info); });
  spdlog::set_pattern("[%H:%M:%S.%e] %^%l%$ %v");

  // CLI11 would report a mistyped subcommand as "a subcommand is required"; name it instead.
  const auto is_command = [&](const CLI::App* sub) { return sub->check_name(argv[1]); };
  if (argc > 1 && argv[1][0] != '-' && app.get_subcommands(is_command).empty()) {
    std::cerr << "retrace: error: unknown command '" << argv[1] << "' (see retrace --help)\n";
    return 2;
  }

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const std::exception& e) {  // retrace::InputError and anything else
    std::cerr << "retrace: error: " << retrace::OneLineMessage(e.what()) << "\n";
    return 1;
  }
  return 0;
}
