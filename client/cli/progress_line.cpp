#include "progress_line.h"

#include <fmt/format.h>
#include <unistd.h>

#include <cstdlib>
#include <string_view>

namespace skinserve::cli {
namespace {

bool StderrIsTerminal() {
  const char* setting = std::getenv("SKINSERVE_PROGRESS");
  if (setting != nullptr && std::string_view(setting) == "0") return false;
  return isatty(STDERR_FILENO) == 1;
}

}  // namespace

ProgressLine::ProgressLine(std::string label, uint64_t total)
    : label_(std::move(label)), total_(total), enabled_(StderrIsTerminal()) {}

void ProgressLine::Update(uint64_t done) {
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  std::lock_guard lock(mutex_);
  // The last frame is always drawn; others at most every 100 ms.
  if (done < total_ && now - last_drawn_ < std::chrono::milliseconds(100)) return;
  last_drawn_ = now;
  Draw(done, now);
}

void ProgressLine::Draw(uint64_t done, std::chrono::steady_clock::time_point now) {
  const double seconds = std::chrono::duration<double>(now - started_).count();
  const double percent = total_ > 0 ? 100.0 * static_cast<double>(done) / total_ : 100.0;
  const std::string line =
      fmt::format("{}: {}/{} frames ({:.0f}%), {:.1f} frames/s", label_, done, total_, percent,
                  seconds > 0 ? static_cast<double>(done) / seconds : 0.0);
  // Padded over the previous line's tail (the rate's width changes).
  fmt::print(stderr, "\r{:<{}}", line, width_);
  width_ = std::max(width_, line.size());
  std::fflush(stderr);
}

void ProgressLine::Finish() {
  if (!enabled_) return;
  std::lock_guard lock(mutex_);
  if (width_ > 0) fmt::print(stderr, "\r{:{}}\r", "", width_);
  std::fflush(stderr);
}

}  // namespace skinserve::cli
