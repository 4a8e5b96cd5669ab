#include "load_stats.h"

#include <algorithm>
#include <cmath>

namespace skinserve::load {

double Percentile(std::vector<double>& values, double q) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  const double rank = std::clamp(q, 0.0, 1.0) * static_cast<double>(values.size() - 1);
  const std::size_t below = static_cast<std::size_t>(std::floor(rank));
  const std::size_t above = std::min(below + 1, values.size() - 1);
  return values[below] + (rank - static_cast<double>(below)) * (values[above] - values[below]);
}

LatencySummary Summarize(std::vector<double> latencies_ms) {
  LatencySummary s;
  if (latencies_ms.empty()) return s;
  s.p50 = Percentile(latencies_ms, 0.50);
  s.p90 = Percentile(latencies_ms, 0.90);
  s.p99 = Percentile(latencies_ms, 0.99);
  s.max = latencies_ms.back();  // sorted by Percentile
  return s;
}

uint64_t RunResult::error_count() const {
  uint64_t total = 0;
  for (const auto& [code, count] : errors) total += count;
  return total;
}

}  // namespace skinserve::load
