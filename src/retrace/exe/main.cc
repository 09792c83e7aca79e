// The `retrace` command-line tool: one binary, one subcommand per job (see `retrace --help`).

#include <algorithm>
#include <iostream>
#include <string>

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include "retrace/exe/commands.h"
#include "retrace/util/error.h"
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
};

// An error message fit for one line of a terminal, whatever an input file put into it: line breaks become spaces,
// other control characters and bytes that are not UTF-8 become '?', and an empty message says so.
std::string OneLineMessage(const std::string& message) {
  std::string result;
  for (size_t i = 0; i < message.size();) {
    const auto byte = static_cast<unsigned char>(message[i]);
    size_t length = byte < 0x80 ? 1 : (byte >> 5) == 0x6 ? 2 : (byte >> 4) == 0xE ? 3 : (byte >> 3) == 0x1E ? 4 : 0;
    for (size_t k = 1; k < length; ++k) {
      if (i + k >= message.size() || (static_cast<unsigned char>(message[i + k]) & 0xC0) != 0x80) length = 0;
    }
    if (byte == '\n' || byte == '\r' || byte == '\t') {
      result += ' ';
    } else if (length == 0 || byte < 0x20 || byte == 0x7F) {
      result += '?';
    } else {
      result.append(message, i, length);
    }
    i += std::max<size_t>(length, 1);
  }
  return result.empty() ? "unknown error (no message)" : result;
}

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
    std::cerr << "retrace: error: " << OneLineMessage(e.what()) << "\n";
    return 1;
  }
  return 0;
}
