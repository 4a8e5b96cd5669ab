#include "load_stats.h"

#include <algorithm>
#include <cmath>

namespace skinserve::load {

void RunResult::CountError(const Status& status, uint64_t n) {
  const char* code = StatusCodeName(status.code());
  errors[code] += n;
  error_examples.emplace(code, status.message());
}

double Percentile(std::vector<double>& values, double q) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  const double rank = std::clamp(q, 0.0, 1.0) * static_cast<double>(values.size() - 1);
  const std::size_t below = static_cast<std::size_t>(std::floor(rank));
  const std::size_t above = std::min(below + 1, values.size() - 1);
  return values[below] + (rank - static_cast<double>(below)) * (values[above] - values[below]);
}

LatencySummary Summarize(std::vector<double> latencies_ms, double percentile) {
  LatencySummary s;
  if (latencies_ms.empty()) return s;
  s.at_percentile = Percentile(latencies_ms, percentile / 100);
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

bool RunResult::within_limit() const {
  return !latency_limit_ms ||
         Summarize(latencies_ms, percentile).at_percentile <= *latency_limit_ms;
}

double RunResult::send_gap_cv() const {
  if (send_gaps < 2) return 0;
  const double n = static_cast<double>(send_gaps);
  const double mean = send_gap_ms_sum / n;
  const double variance = std::max(0.0, (send_gap_ms_sq_sum - n * mean * mean) / (n - 1));
  return mean > 0 ? std::sqrt(variance) / mean : 0;
}

std::optional<double> RunResult::server_cpu_us_per_frame() const {
  if (!server_cpu_seconds || !(server_frames > 0)) return std::nullopt;
  return *server_cpu_seconds * 1e6 / server_requests();
}

std::optional<double> RunResult::server_cpu_us_per_character() const {
  const auto per_frame = server_cpu_us_per_frame();
  if (!per_frame) return std::nullopt;
  return *per_frame / characters_per_frame();
}

std::optional<double> RunResult::server_cpu_over_compute() const {
  const auto per_frame = server_cpu_us_per_frame();
  const double compute_us = mean(server_compute_ms_sum) * 1e3;
  if (!per_frame || compute_us <= 0) return std::nullopt;
  return *per_frame / compute_us;
}

RunResult MergeResults(const std::vector<RunResult>& windows) {
  RunResult merged = windows.front();
  for (std::size_t i = 1; i < windows.size(); ++i) {
    const RunResult& w = windows[i];
    merged.frames += w.frames;
    merged.seconds += w.seconds;
    merged.latencies_ms.insert(merged.latencies_ms.end(), w.latencies_ms.begin(),
                               w.latencies_ms.end());
    merged.server_queue_ms_sum += w.server_queue_ms_sum;
    merged.server_compute_ms_sum += w.server_compute_ms_sum;
    merged.server_encode_ms_sum += w.server_encode_ms_sum;
    for (const auto& [code, count] : w.errors) merged.errors[code] += count;
    for (const auto& [code, message] : w.error_examples)
      merged.error_examples.emplace(code, message);
    merged.checked += w.checked;
    merged.mismatches += w.mismatches;
    merged.sent += w.sent;
    merged.late += w.late;
    merged.dropped += w.dropped;
    merged.late_sends += w.late_sends;
    merged.send_lag_ms_sum += w.send_lag_ms_sum;
    merged.send_gaps += w.send_gaps;
    merged.send_gap_ms_sum += w.send_gap_ms_sum;
    merged.send_gap_ms_sq_sum += w.send_gap_ms_sq_sum;
    merged.skinning_ms_sum += w.skinning_ms_sum;
    merged.breakdown_encode_ms_sum += w.breakdown_encode_ms_sum;
    merged.transport_ms_sum += w.transport_ms_sum;
    merged.metrics_scraped = merged.metrics_scraped && w.metrics_scraped;
    for (const auto& [series, delta] : w.server_metrics) merged.server_metrics[series] += delta;
    merged.server_frames += w.server_frames;
    merged.server_cpu_seconds =
        merged.server_cpu_seconds && w.server_cpu_seconds
            ? std::optional(*merged.server_cpu_seconds + *w.server_cpu_seconds)
            : std::nullopt;
  }
  return merged;
}

}  // namespace skinserve::load
