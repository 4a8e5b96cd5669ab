#include "report_columns.h"

#include <optional>

#include "load_report.h"
#include "server_metrics.h"

namespace skinserve::load {
namespace {

using nlohmann::json;

json OrNull(bool applies, json value) { return applies ? std::move(value) : json(nullptr); }
json OrNull(const std::optional<double>& value) { return value ? json(*value) : json(nullptr); }

// The row's backend's label in the server's per-backend series.
std::vector<std::string> BackendLabel(const RunResult& r) {
  return {"backend=\"" + r.backend + "\""};
}

using R = const RunResult&;
using All = const std::vector<RunResult>&;

// What was run: the mesh, the answers asked for, the streams and the offered rate.
std::vector<ReportColumn> RunColumns() {
  return {
      {"backend", [](R r, All) { return json(r.backend); }},
      {"vertices", [](R r, All) { return json(r.vertices); }},
      {"bones", [](R r, All) { return json(r.bones); }},
      {"normals", [](R r, All) { return json(r.normals); }},
      {"tangents", [](R r, All) { return json(r.tangents); }},
      {"encoding", [](R r, All) { return json(r.encoding); }},
      {"rest_encoding", [](R r, All) { return json(r.rest_encoding); }},
      {"instances", [](R r, All) { return json(r.instances); }},
      {"characters_per_tick", [](R r, All) { return json(r.characters_per_tick); }},
      {"data_plane", [](R r, All) { return json(r.data_plane); }},
      {"pose", [](R r, All) { return json(r.pose); }},
      {"clip", [](R r, All) { return OrNull(r.pose, r.clip); }},
      {"streams", [](R r, All) { return json(r.streams); }},
      {"rate", [](R r, All) { return json(r.rate); }},
      {"offered_frames_per_second", [](R r, All) { return json(r.rate * r.streams); }},
      {"arrivals", [](R r, All) { return OrNull(!r.arrivals.empty(), r.arrivals); }},
  };
}

// What came back per second.
std::vector<ReportColumn> ThroughputColumns() {
  return {
      {"frames", [](R r, All) { return json(r.frames); }},
      {"seconds", [](R r, All) { return json(r.seconds); }},
      {"frames_per_second", [](R r, All) { return json(r.frames_per_second()); }},
      {"characters_per_second", [](R r, All) { return json(r.characters_per_second()); }},
      {"vertices_per_second", [](R r, All) { return json(r.vertices_per_second()); }},
      {"megabytes_per_second", [](R r, All) { return json(r.megabytes_per_second()); }},
  };
}

// The latency percentiles and the limit they are held to.
std::vector<ReportColumn> LatencyColumns() {
  const auto latency = [](double LatencySummary::*member) {
    return [member](R r, All) { return json(Summarize(r.latencies_ms, r.percentile).*member); };
  };
  return {
      {"latency_ms/p50", latency(&LatencySummary::p50)},
      {"latency_ms/p90", latency(&LatencySummary::p90)},
      {"latency_ms/p99", latency(&LatencySummary::p99)},
      {"latency_ms/max", latency(&LatencySummary::max)},
      {"percentile", [](R r, All) { return json(r.percentile); }},
      {"latency_ms/at_percentile", latency(&LatencySummary::at_percentile)},
      {"latency_limit_ms",
       [](R r, All) {
         return OrNull(r.latency_limit_ms.has_value(), r.latency_limit_ms.value_or(0));
       }},
      {"within_limit",
       [](R r, All) { return OrNull(r.latency_limit_ms.has_value(), r.within_limit()); }},
  };
}

// Where a frame's time went: the server's timings and the latency breakdown.
std::vector<ReportColumn> BreakdownColumns() {
  const auto mean = [](double RunResult::*sum) {
    return [sum](R r, All) { return json(r.mean(r.*sum)); };
  };
  return {
      {"server_ms/queue", mean(&RunResult::server_queue_ms_sum)},
      {"server_ms/compute", mean(&RunResult::server_compute_ms_sum)},
      {"server_ms/encode", mean(&RunResult::server_encode_ms_sum)},
      {"breakdown_ms/send_lag", mean(&RunResult::send_lag_ms_sum)},
      {"breakdown_ms/queue", mean(&RunResult::server_queue_ms_sum)},
      {"breakdown_ms/skinning", mean(&RunResult::skinning_ms_sum)},
      {"breakdown_ms/encode", mean(&RunResult::breakdown_encode_ms_sum)},
      {"breakdown_ms/transport", mean(&RunResult::transport_ms_sum)},
      {"breakdown_ms/latency_mean",
       [](R r, All) {
         double sum = 0;
         for (double l : r.latencies_ms) sum += l;
         return json(r.mean(sum));
       }},
  };
}

// Errors, checks, sends and drops, trials, and the speedup over serial.
std::vector<ReportColumn> CountColumns() {
  return {
      {"errors", [](R r, All) { return json(r.errors); }},
      {"checked", [](R r, All) { return json(r.checked); }},
      {"mismatches", [](R r, All) { return json(r.mismatches); }},
      {"sent", [](R r, All) { return json(r.sent); }},
      {"late", [](R r, All) { return json(r.late); }},
      {"dropped", [](R r, All) { return json(r.dropped); }},
      {"late_sends", [](R r, All) { return json(r.late_sends); }},
      {"send_gap_ms/mean", [](R r, All) { return json(r.send_gap_mean_ms()); }},
      {"send_gap_ms/cv", [](R r, All) { return json(r.send_gap_cv()); }},
      {"trials", [](R r, All) { return json(r.trials); }},
      {"stable", [](R r, All) { return OrNull(r.stable.has_value(), r.stable.value_or(false)); }},
      {"speedup_over_serial",
       [](R r, All all) {
         const double serial = SerialFramesPerSecond(all, r);
         return OrNull(serial > 0, serial > 0 ? r.frames_per_second() / serial : 0);
       }},
  };
}

// The server's own counts (--metrics-url).
std::vector<ReportColumn> ServerCpuColumns() {
  const auto metric = [](const char* family) {
    return [family](R r, All) {
      return OrNull(r.metrics_scraped, SumSeries(r.server_metrics, family, BackendLabel(r)));
    };
  };
  return {
      // --metrics-url: process_cpu_seconds_total's increase over the measured part, and the
      // frames the server answered between the same scrapes (every backend).
      {"server_cpu_seconds",
       [](R r, All) {
         return OrNull(r.server_cpu_seconds.has_value(), r.server_cpu_seconds.value_or(0));
       }},
      {"server_frames", [](R r, All) { return OrNull(r.metrics_scraped, r.server_frames); }},
      {"server_cpu_us_per_frame", [](R r, All) { return OrNull(r.server_cpu_us_per_frame()); }},
      {"server_cpu_us_per_character",
       [](R r, All) { return OrNull(r.server_cpu_us_per_character()); }},
      {"server_cpu_over_compute", [](R r, All) { return OrNull(r.server_cpu_over_compute()); }},
      {"server_metrics/frames", metric("skinserve_frames_total")},
      {"server_metrics/frame_errors", metric("skinserve_frame_errors_total")},
      {"server_metrics/queue_seconds_sum", metric("skinserve_frame_queue_seconds_sum")},
      {"server_metrics/compute_seconds_sum", metric("skinserve_frame_compute_seconds_sum")},
      {"server_metrics/encode_seconds_sum", metric("skinserve_frame_encode_seconds_sum")},
      {"server_metrics/server_seconds_sum", metric("skinserve_frame_server_seconds_sum")},
      {"server_metrics/deltas",
       [](R r, All) { return OrNull(r.metrics_scraped, json(r.server_metrics)); }},
  };
}

std::vector<ReportColumn> MakeColumns() {
  std::vector<ReportColumn> columns;
  for (auto group : {RunColumns, ThroughputColumns, LatencyColumns, BreakdownColumns, CountColumns,
                     ServerCpuColumns}) {
    for (ReportColumn& column : group()) columns.push_back(std::move(column));
  }
  return columns;
}

}  // namespace

const std::vector<ReportColumn>& ReportColumns() {
  static const std::vector<ReportColumn> columns = MakeColumns();
  return columns;
}

std::string CsvColumnName(const std::string& path) {
  std::string name = path;
  for (char& c : name) c = c == '/' ? '.' : c;
  return name;
}

json JsonRow(const RunResult& row, const std::vector<RunResult>& all) {
  json item = json::object();
  for (const ReportColumn& column : ReportColumns()) {
    item[json::json_pointer("/" + column.path)] = column.value(row, all);
  }
  return item;
}

std::string CsvCell(const json& value) {
  std::string text;
  if (value.is_null()) return text;
  if (value.is_string()) {
    text = value.get<std::string>();
  } else if (value.is_object()) {
    for (const auto& [key, v] : value.items()) {
      text +=
          (text.empty() ? "" : ";") + key + "=" + (v.is_string() ? v.get<std::string>() : v.dump());
    }
  } else {
    text = value.dump();
  }
  if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
  std::string quoted = "\"";
  for (char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

}  // namespace skinserve::load
