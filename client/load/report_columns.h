// The columns of a load report, listed once: --json writes them as nested objects
// ("latency_ms/p50" is {"latency_ms": {"p50": ...}}), --csv as one column each, named with
// dots ("latency_ms.p50"), so the two cannot drift apart.
#pragma once

#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "load_stats.h"

namespace skinserve::load {

struct ReportColumn {
  std::string path;  // JSON pointer without its leading '/': "latency_ms/p50"
  // The row's value; null when it does not apply (CSV: an empty cell). `all`: every row of
  // the report (the speedup over serial looks up serial's row).
  std::function<nlohmann::json(const RunResult& row, const std::vector<RunResult>& all)> value;
};

const std::vector<ReportColumn>& ReportColumns();

// "latency_ms/p50" -> "latency_ms.p50".
std::string CsvColumnName(const std::string& path);
// One row as JSON (nested by path).
nlohmann::json JsonRow(const RunResult& row, const std::vector<RunResult>& all);
// A value as a CSV cell: numbers and booleans as JSON writes them (so that both files hold
// the same text), strings as they are, objects as KEY=VALUE;... , null as empty; quoted
// (RFC 4180) when it holds a comma, a quote or a line break.
std::string CsvCell(const nlohmann::json& value);

}  // namespace skinserve::load
