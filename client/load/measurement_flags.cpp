#include "measurement_flags.h"

#include <fmt/format.h>

#include <cmath>
#include <cstdlib>

namespace skinserve::load {
namespace {

inline constexpr std::size_t kMaxRates = 1000;

}  // namespace

void AddMeasurementFlags(CLI::App& app, MeasurementFlags& flags) {
  app.add_option("--rate-range", flags.rate_range,
                 "open loop at each rate of START:END[:STEP] frames/s per stream (as --rate; "
                 "STEP 1 by default): one measurement and one report row per rate")
      ->check([](const std::string& text) {
        auto rates = ParseRateRange(text);
        // CLI11 names the option itself: "--rate-range: '10:5': END must be >= START".
        return rates.ok() ? std::string()
                          : rates.status().message().substr(std::string("--rate-range ").size());
      })
      ->excludes("--rate")
      ->excludes("--capacity");
  app.add_option("--arrivals", flags.arrivals,
                 "open loop: constant (each stream every 1/rate, the streams staggered evenly) "
                 "or poisson (exponential gaps, seeded by --seed)")
      ->check(CLI::IsMember({"constant", "poisson"}))
      ->capture_default_str();
  app.add_option("--percentile", flags.measure.percentile,
                 "the latency percentile of --latency-limit-ms, of --capacity's rule and of the "
                 "headline column (0..100)")
      ->check(CLI::Range(0.0, 100.0))
      ->capture_default_str();
  app.add_option("--latency-limit-ms", flags.latency_limit_ms,
                 "rows whose latency at --percentile exceeds this are over the limit; a "
                 "--rate-range stops after the first such rate (--capacity: default one frame)")
      ->check(CLI::PositiveNumber);
  app.add_option("--max-trials", flags.measure.max_trials,
                 "measurement windows of --duration per row at most; 3 or more applies the "
                 "stability rule (the last 3 windows agree), 1 measures one window")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  app.add_option("--stability-percentage", flags.measure.stability_percent,
                 "the last 3 windows agree when each is within this % of their mean in frames/s "
                 "and in latency at --percentile")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--metrics-url", flags.measure.metrics_url,
                 "the server's Prometheus endpoint (http://HOST:PORT[/metrics], its "
                 "--metrics-listen): scraped when each window's measured part begins (after the "
                 "warm-up) and after it ends; its counters' deltas go in the report, and the "
                 "server's CPU (process_cpu_seconds_total) over the frames it answered between "
                 "the scrapes: per frame, per character and over the compute column "
                 "(server_cpu_us_per_frame, server_cpu_us_per_character, "
                 "server_cpu_over_compute); without it those are empty");
}

Result<std::vector<double>> ParseRateRange(const std::string& text) {
  const auto bad = [&](const std::string& why) {
    return InvalidArgument(fmt::format("--rate-range '{}': {}", text, why));
  };
  std::vector<double> parts;
  std::size_t from = 0;
  while (true) {
    const std::size_t colon = text.find(':', from);
    const std::string item = text.substr(from, colon - from);
    char* end = nullptr;
    const double value = std::strtod(item.c_str(), &end);
    if (item.empty() || end != item.c_str() + item.size() || !std::isfinite(value)) {
      return bad(fmt::format("'{}' is not a number (expected START:END[:STEP])", item));
    }
    parts.push_back(value);
    if (colon == std::string::npos) break;
    from = colon + 1;
  }
  if (parts.size() < 2 || parts.size() > 3) return bad("expected START:END[:STEP]");
  const double start = parts[0], last = parts[1], step = parts.size() == 3 ? parts[2] : 1;
  if (start <= 0) return bad("START must be > 0 frames/s");
  if (last < start) return bad("END must be >= START");
  if (step <= 0) return bad("STEP must be > 0");
  if ((last - start) / step + 1 > kMaxRates) {
    return bad(fmt::format("more than {} rates", kMaxRates));
  }
  std::vector<double> rates;
  for (std::size_t i = 0;; ++i) {
    const double rate = start + static_cast<double>(i) * step;
    if (rate > last + 1e-9 * step) break;
    rates.push_back(rate);
  }
  return rates;
}

}  // namespace skinserve::load
