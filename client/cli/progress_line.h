// A one-line progress display for long subcommands (animate): frames done of the total
// and the rate, redrawn in place on stderr at most 10 times a second. It draws only when
// stderr is a terminal: in pipes, files and CI logs it writes nothing at all.
#pragma once

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <mutex>
#include <string>

namespace skinserve::cli {

class ProgressLine {
 public:
  // `label` starts the line, e.g. "animate"; `total` frames are expected.
  ProgressLine(std::string label, uint64_t total);
  // Drawn when stderr is a terminal (SKINSERVE_PROGRESS=0 turns it off there too).
  bool enabled() const { return enabled_; }
  // `done` frames of the total are finished; thread-safe.
  void Update(uint64_t done);
  // Clears the line (the final report follows on stdout).
  void Finish();

 private:
  void Draw(uint64_t done, std::chrono::steady_clock::time_point now);

  const std::string label_;
  const uint64_t total_;
  const bool enabled_;
  const std::chrono::steady_clock::time_point started_ = std::chrono::steady_clock::now();
  std::mutex mutex_;
  std::chrono::steady_clock::time_point last_drawn_{};
  std::size_t width_ = 0;  // of the last line drawn, to clear it
};

}  // namespace skinserve::cli
