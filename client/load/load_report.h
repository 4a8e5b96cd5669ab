// How a load run is shown: a table on stdout, the paper's speedup tables for a sweep,
// and --json, --csv and --plot files.
#pragma once

#include <string>
#include <vector>

#include "load_stats.h"
#include "skinserve/model/status.h"

namespace skinserve::load {

void PrintTable(const std::vector<RunResult>& results, bool open_loop);
// The server CPU columns of a text table (server_cpu_us_per_frame, _per_character and
// _over_compute, for tables of rows measured with --metrics-url): the header, and a row's
// cells ("-" where not known).
std::string ServerCpuHeader();
std::string ServerCpuCells(const RunResult& r);
// The paper's tables 2 and 3 layout: per backend, vertices x bones, speedup over serial.
void PrintSpeedupTables(const std::vector<RunResult>& results);
// frames/s of `serial` on the same workload in the same run; 0 if not measured.
double SerialFramesPerSecond(const std::vector<RunResult>& results, const RunResult& of);

Status WriteJson(const std::string& path, const std::vector<RunResult>& results);
Status WriteCsv(const std::string& path, const std::vector<RunResult>& results);
// Throughput bars per backend and workload; with a sweep, also a speedup heat map (a
// second image next to `path`, "-speedup" before the extension). Uses gnuplot.
Status WritePlot(const std::string& path, const std::vector<RunResult>& results);
// Where WritePlot puts a sweep's speedup heat map: FILE-speedup.png next to FILE.png.
std::string SpeedupPlotPath(const std::string& plot_path);

}  // namespace skinserve::load
