// One report row: a load run repeated in windows under the stability rule, with the
// server's /metrics scraped around each window (--max-trials, --stability-percentage,
// --percentile, --latency-limit-ms, --metrics-url).
#pragma once

#include <optional>
#include <string>

#include "load_runner.h"
#include "load_stats.h"
#include "skinserve/model/status.h"

namespace skinserve::load {

struct MeasureOptions {
  int max_trials = 1;             // windows at most; >= 3 applies the stability rule
  double stability_percent = 10;  // the last 3 windows within this % of their mean
  double percentile = 99;         // of the latency limit and the headline latency
  std::optional<double> latency_limit_ms;
  std::string metrics_url;  // empty: no scraping
};

// Runs windows of `config` (the first with its warm-up, the next without) until the last
// three agree or `max_trials` ran, or a window failed; the row merges the last (up to)
// three. With a metrics URL, scrapes when each window's measured part begins and after it
// ends (RunLoad's MeasuredPartHooks): the row holds the counters' deltas and the server's
// CPU seconds over its windows' measured parts. A failed scrape is UNAVAILABLE naming the URL.
Result<RunResult> Measure(const RunConfig& config, const std::vector<UploadedMesh>& meshes,
                          const Progress& progress, const MeasureOptions& options);

}  // namespace skinserve::load
