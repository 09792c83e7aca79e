#pragma once

// Helpers for tests: where the shared real data lives, and skipping cleanly when it is absent.

#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "retrace/util/error.h"

namespace retrace::testing {

// Folder of the shared real camera data (`RETRACE_DATA` environment variable, else ../shared/data next to the
// source tree). May not exist.
std::filesystem::path SharedDataDir();

// Path of `relative` inside the shared data folder, or an empty path when it does not exist.
std::filesystem::path SharedDataPath(const std::string& relative);

// A fresh empty temporary folder for one test, removed by the caller or left for inspection.
std::filesystem::path MakeTempDir(const std::string& prefix);

// The message of the InputError that `f()` throws; a test failure (and "") when it throws none.
template <typename F>
std::string ErrorOf(F f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no InputError thrown";
  return "";
}

}  // namespace retrace::testing

// Skips the current GoogleTest test when the shared data `relative` is absent; otherwise defines `var` as its path.
#define RETRACE_REQUIRE_SHARED_DATA(var, relative)                                   \
  const std::filesystem::path var = ::retrace::testing::SharedDataPath(relative);   \
  if (var.empty()) {                                                                \
    GTEST_SKIP() << "shared data '" << relative << "' not found; skipping";          \
  }
