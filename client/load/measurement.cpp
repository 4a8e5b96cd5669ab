#include "measurement.h"

#include <algorithm>
#include <vector>

#include "server_metrics.h"
#include "stability.h"

namespace skinserve::load {

Result<RunResult> Measure(const RunConfig& config, const std::vector<UploadedMesh>& meshes,
                          const Progress& progress, const MeasureOptions& options) {
  const bool scrape = !options.metrics_url.empty();
  if (scrape) {  // a wrong URL fails now, not after a window's --duration
    if (auto probe = ScrapeMetrics(options.metrics_url); !probe.ok()) return probe.status();
  }
  const int trials = std::max(options.max_trials, 1);
  const bool rule = trials >= static_cast<int>(kStableWindows);
  std::vector<RunResult> windows;
  bool stable = false;
  for (int trial = 0; trial < trials && !stable; ++trial) {
    RunConfig window = config;
    if (trial > 0) window.warmup_seconds = 0;  // the server is warm: measure straight away
    window.arrivals_seed = config.arrivals_seed + trial;  // each window its own Poisson draws
    const Progress window_progress =
        progress ? Progress([&, trial](double f) { progress((trial + f) / trials); }) : nullptr;
    // The scrapes bracket the window's measured part (not its warm-up): the server's CPU
    // and counters over the frames this row counts, give or take those in flight at its ends.
    Result<MetricSamples> before = MetricSamples(), after = MetricSamples();
    MeasuredPartHooks hooks;
    if (scrape) {
      hooks.begin = [&] { before = ScrapeMetrics(options.metrics_url); };
      hooks.end = [&] { after = ScrapeMetrics(options.metrics_url); };
    }
    RunResult r = RunLoad(window, meshes, window_progress, hooks);
    r.percentile = options.percentile;
    if (scrape) {
      if (!before.ok()) return before.status();
      if (!after.ok()) return after.status();
      r.server_metrics = MetricDeltas(*before, *after);
      r.server_cpu_seconds = CpuSecondsBetween(*before, *after);
      r.server_frames = SumSeries(r.server_metrics, "skinserve_frames_total");
      r.metrics_scraped = true;
    }
    windows.push_back(std::move(r));
    if (windows.back().failed()) break;  // errors do not settle: report them now
    stable = rule && LastWindowsAgree(windows, options.stability_percent, options.percentile);
  }
  const std::size_t kept = std::min(windows.size(), kStableWindows);
  RunResult row = MergeResults(std::vector<RunResult>(windows.end() - kept, windows.end()));
  row.trials = static_cast<int>(windows.size());
  if (rule) row.stable = stable;
  row.latency_limit_ms = options.latency_limit_ms;
  return row;
}

}  // namespace skinserve::load
