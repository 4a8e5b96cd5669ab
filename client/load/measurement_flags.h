// The command-line options of how each measurement is made (rates, arrivals, percentile,
// stability, server metrics), registered apart from main's so that each stays short.
#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "measurement.h"
#include "skinserve/model/status.h"

namespace skinserve::load {

struct MeasurementFlags {
  std::string rate_range;  // START:END[:STEP], frames/s per stream
  std::string arrivals = "constant";
  MeasureOptions measure;
  double latency_limit_ms = 0;  // 0: none (--capacity: one frame period)
};

void AddMeasurementFlags(CLI::App& app, MeasurementFlags& flags);

// "START:END[:STEP]" -> START, START + STEP, ... up to END (within 1e-9 of a step), each
// > 0; STEP defaults to 1. INVALID_ARGUMENT naming --rate-range and what is wrong.
Result<std::vector<double>> ParseRateRange(const std::string& text);

}  // namespace skinserve::load
