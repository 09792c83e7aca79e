#include <iostream>

#include <Eigen/Core>
#include <opencv2/core/version.hpp>

#include "retrace/exe/commands.h"
#include "retrace/util/version.h"

namespace retrace {

void RegisterVersionCommand(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand("version", "Print the version of retrace and of its main libraries");
  cmd->callback([]() {
    std::cout << "retrace " << Version() << " (OpenCV " << CV_VERSION << ", Eigen " << EIGEN_WORLD_VERSION << "."
              << EIGEN_MAJOR_VERSION << "." << EIGEN_MINOR_VERSION << ")\n";
  });
}

}  // namespace retrace
