#include "retrace/util/progress.h"

#include <unistd.h>

#include <cstdio>
#include <string>

namespace retrace {

ProgressBar::ProgressBar(std::string label, size_t total, bool enabled)
    : label_(std::move(label)),
      total_(total),
      enabled_(enabled),
      interactive_(isatty(fileno(stderr)) != 0),
      start_(std::chrono::steady_clock::now()),
      last_draw_(start_) {}

ProgressBar::~ProgressBar() { Finish(); }

void ProgressBar::Advance(size_t steps, const std::string& status) {
  done_ += steps;
  status_ = status;
  Draw(false);
}

void ProgressBar::Finish() {
  if (finished_) return;
  finished_ = true;
  if (!enabled_) return;
  Draw(true);
  if (interactive_) std::fputc('\n', stderr);
}

void ProgressBar::Draw(bool force) {
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  const double elapsed = std::chrono::duration<double>(now - start_).count();
  const double rate = elapsed > 0 ? done_ / elapsed : 0.0;
  // "12/300", or "12" when the total is not known.
  const std::string count = total_ > 0 ? std::to_string(done_) + "/" + std::to_string(total_) : std::to_string(done_);
  if (interactive_) {
    if (!force && now - last_draw_ < std::chrono::milliseconds(100)) return;
    last_draw_ = now;
    constexpr int kWidth = 30;
    const double fraction = total_ > 0 ? std::min(1.0, double(done_) / total_) : 0.0;
    const int filled = static_cast<int>(fraction * kWidth);
    std::fprintf(stderr, "\r%s [%s%s] %s %.1f/s %s\033[K", label_.c_str(), std::string(filled, '#').c_str(),
                 std::string(kWidth - filled, '.').c_str(), count.c_str(), rate, status_.c_str());
  } else {
    const int decile = total_ > 0 ? static_cast<int>(10.0 * done_ / total_) : 0;
    if (!force && decile == last_decile_) return;
    if (force && done_ == last_printed_done_) return;  // the final line was printed already
    last_decile_ = decile;
    last_printed_done_ = done_;
    std::fprintf(stderr, "%s: %s (%.1f/s) %s\n", label_.c_str(), count.c_str(), rate, status_.c_str());
  }
  std::fflush(stderr);
}

}  // namespace retrace
