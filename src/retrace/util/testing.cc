#include "retrace/util/testing.h"

#include <unistd.h>

#include <atomic>
#include <cstdlib>

namespace retrace::testing {

std::filesystem::path SharedDataDir() {
  if (const char* env = std::getenv("RETRACE_DATA"); env != nullptr && *env != '\0') return env;
#ifdef RETRACE_SHARED_DATA_DIR
  return RETRACE_SHARED_DATA_DIR;
#else
  return "../shared/data";
#endif
}

std::filesystem::path SharedDataPath(const std::string& relative) {
  const std::filesystem::path path = SharedDataDir() / relative;
  std::error_code ec;
  return std::filesystem::exists(path, ec) ? path : std::filesystem::path();
}

std::filesystem::path MakeTempDir(const std::string& prefix) {
  static std::atomic<int> counter{0};
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("retrace_" + prefix + "_" + std::to_string(getpid()) + "_" +
                                     std::to_string(counter++));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace retrace::testing
