#pragma once

// Scenario files (YAML or JSON, which is YAML too): reading with precise errors, and writing with comments.
//
// Every key is optional (missing keys keep the defaults of scenario.h); unknown keys and values of the wrong type
// are errors. A bad file throws InputError naming the file, the line and the key, e.g.
//   "town.yaml: line 14: camera.width: expected an integer, got 'wide'".

#include <filesystem>
#include <string>

#include "retrace/sim/scenario.h"

namespace retrace {

// Reads a scenario file. Throws InputError on unreadable files, syntax errors, unknown keys and bad values.
Scenario ReadScenario(const std::filesystem::path& path);
// Parses scenario text; `source` names it in errors.
Scenario ParseScenario(const std::string& text, const std::string& source);

// The scenario as YAML with a comment on every field (`retrace sim example-scenario` prints the defaults).
std::string ScenarioToYaml(const Scenario& scenario);

}  // namespace retrace
