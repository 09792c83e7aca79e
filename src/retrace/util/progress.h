#pragma once

// A progress bar for long runs (rendering, teach, repeat). On a terminal it redraws one line on stderr; otherwise
// (logs, CI) it prints a plain line every 10%, so logs stay short.

#include <chrono>
#include <cstddef>
#include <string>

namespace retrace {

class ProgressBar {
 public:
  // `total` = number of steps (0 if unknown), `label` is printed in front of the bar.
  ProgressBar(std::string label, size_t total, bool enabled = true);
  ~ProgressBar();

  // Advances by `steps`; `status` is an optional short text shown after the bar.
  void Advance(size_t steps = 1, const std::string& status = "");
  // Prints the final line (called by the destructor if not called before).
  void Finish();

 private:
  void Draw(bool force);

  std::string label_;
  size_t total_;
  size_t done_ = 0;
  bool enabled_;
  bool interactive_;
  bool finished_ = false;
  int last_decile_ = -1;
  size_t last_printed_done_ = static_cast<size_t>(-1);
  std::string status_;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_draw_;
};

}  // namespace retrace
