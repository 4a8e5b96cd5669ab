#include "stability.h"

#include <cmath>

namespace skinserve::load {
namespace {

bool WithinOfMean(const std::vector<double>& values, double percent) {
  double mean = 0;
  for (double v : values) mean += v / static_cast<double>(values.size());
  for (double v : values) {
    if (std::abs(v - mean) > percent / 100 * std::abs(mean)) return false;
  }
  return true;
}

}  // namespace

bool LastWindowsAgree(const std::vector<RunResult>& windows, double percent, double percentile) {
  if (windows.size() < kStableWindows) return false;
  std::vector<double> throughput, latency;
  for (std::size_t i = windows.size() - kStableWindows; i < windows.size(); ++i) {
    throughput.push_back(windows[i].frames_per_second());
    latency.push_back(Summarize(windows[i].latencies_ms, percentile).at_percentile);
  }
  return WithinOfMean(throughput, percent) && WithinOfMean(latency, percent);
}

}  // namespace skinserve::load
