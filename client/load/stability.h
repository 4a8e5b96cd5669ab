// The stability rule of a measurement, after perf_analyzer's: windows of --duration repeat
// until the last three agree, each within --stability-percentage of their mean in
// frames/s and in the latency at --percentile, or --max-trials windows have run.
#pragma once

#include <vector>

#include "load_stats.h"

namespace skinserve::load {

inline constexpr std::size_t kStableWindows = 3;

// True when `windows` has at least kStableWindows and its last kStableWindows agree within
// `percent` % of their mean in frames/s and in latency at `percentile` (0..100).
bool LastWindowsAgree(const std::vector<RunResult>& windows, double percent, double percentile);

}  // namespace skinserve::load
