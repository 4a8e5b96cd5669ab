// The server's Prometheus /metrics, scraped before and after a measurement (--metrics-url):
// what the server says it did during the measurement, beside what the client saw.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "skinserve/model/status.h"

namespace skinserve::load {

// Samples by series, `name{label="value",...}` with the labels sorted by name (as written
// when there are none: `name`).
using MetricSamples = std::map<std::string, double>;

// Prometheus' text exposition format: comments and blank lines skipped; label values may
// hold escaped quotes, commas, braces and spaces; values may be NaN or +/-Inf; an optional
// timestamp follows. Only series of counters and the _sum/_count of histograms and
// summaries (by their # TYPE; untyped series too) are kept: the ones whose difference means
// something (buckets left out: too many to report). A malformed line is INVALID_ARGUMENT
// naming its line number.
Result<MetricSamples> ParseMetricsText(const std::string& text);

// GET `url` (http://HOST[:PORT][/PATH], path /metrics when none) over a plain socket, with a
// `timeout_seconds` limit; the body parsed. Errors name the URL.
Result<MetricSamples> ScrapeMetrics(const std::string& url, double timeout_seconds = 5);

// after - before for every series in `after` (a series new in `after` counts from 0); a
// series that went down (the server restarted) keeps its `after` value, as Prometheus'
// increase() does. Zero deltas are left out.
MetricSamples MetricDeltas(const MetricSamples& before, const MetricSamples& after);

// The server process's CPU seconds (user + system, process_cpu_seconds_total, which the
// server reads from /proc/self/stat in clock ticks: 10 ms steps) spent from `before` to
// `after`; none when either scrape lacks the series or it went down (the server restarted:
// the CPU before the restart is lost, so no difference can be made up).
std::optional<double> CpuSecondsBetween(const MetricSamples& before, const MetricSamples& after);

// The sum of the deltas of family `name` whose labels include every `label="value"` in
// `labels` (e.g. {"backend=\"sse\""}).
double SumSeries(const MetricSamples& samples, const std::string& name,
                 const std::vector<std::string>& labels = {});

}  // namespace skinserve::load
