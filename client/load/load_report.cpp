#include "load_report.h"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>

#include "report_columns.h"

namespace skinserve::load {
namespace {

std::string ErrorsText(const RunResult& r) {
  std::string text;
  for (const auto& [code, count] : r.errors)
    text += fmt::format("{}{}={}", text.empty() ? "" : ",", code, count);
  return text.empty() ? "0" : text;
}

// The backend, with the encoding and crowd size when they are not float32 x 1, "+shm"
// for the shared-memory data plane ("+socket" with requests on the frame socket), "+tickN" for
// ticks of N characters and "+pose" for frames posed on the server (--animate synthetic),
// "+pose:CLIP" playing a glTF file's clip.
std::string BackendLabel(const RunResult& r) {
  const std::string pose =
      !r.pose ? "" : (r.clip.empty() || r.clip == "synthetic" ? "+pose" : "+pose:" + r.clip);
  const std::string shm =
      (r.data_plane == "grpc" ? "" : "+" + r.data_plane) +
      (r.characters_per_tick > 0 ? fmt::format("+tick{}", r.characters_per_tick) : std::string()) +
      pose;
  if (r.encoding == "float32" && r.instances <= 1) return r.backend + shm;
  return r.instances > 1 ? fmt::format("{}/{}x{}{}", r.backend, r.encoding, r.instances, shm)
                         : fmt::format("{}/{}{}", r.backend, r.encoding, shm);
}

// Under the table: each row's errors by code, with the first one's message.
void PrintErrorExamples(const std::vector<RunResult>& results) {
  for (const RunResult& r : results) {
    for (const auto& [code, message] : r.error_examples) {
      fmt::print("errors: {} {} x{}, the first: {}\n", BackendLabel(r), code, r.errors.at(code),
                 message);
    }
  }
}

}  // namespace

std::string ServerCpuHeader() {
  return fmt::format(" {:>10} {:>10} {:>8}", "cpu us/fr", "cpu us/ch", "cpu/comp");
}

std::string ServerCpuCells(const RunResult& r) {
  const auto cell = [](std::optional<double> value, int width, int precision) {
    return value ? fmt::format("{:>{}.{}f}", *value, width, precision)
                 : fmt::format("{:>{}}", "-", width);
  };
  return fmt::format(" {} {} {}", cell(r.server_cpu_us_per_frame(), 10, 1),
                     cell(r.server_cpu_us_per_character(), 10, 1),
                     cell(r.server_cpu_over_compute(), 8, 2));
}

double SerialFramesPerSecond(const std::vector<RunResult>& results, const RunResult& of) {
  for (const RunResult& r : results) {
    if (r.backend == "serial" && r.vertices == of.vertices && r.bones == of.bones &&
        r.normals == of.normals && r.tangents == of.tangents) {
      return r.frames_per_second();
    }
  }
  return 0;
}

void PrintTable(const std::vector<RunResult>& results, bool open_loop) {
  const double percentile = results.empty() ? 99 : results.front().percentile;
  const bool trials = std::any_of(results.begin(), results.end(),
                                  [](const RunResult& r) { return r.stable.has_value(); });
  const bool rates = std::any_of(results.begin(), results.end(), [&](const RunResult& r) {
    return r.rate != results.front().rate;
  });
  const bool cpu = std::any_of(results.begin(), results.end(),
                               [](const RunResult& r) { return r.server_cpu_seconds.has_value(); });
  // Crowds and ticks: characters/s beside frames/s (a tick is one frame of the row).
  const bool characters = std::any_of(results.begin(), results.end(), [](const RunResult& r) {
    return r.characters_per_frame() > 1;
  });
  fmt::print(
      "{:<16}{} {:>8} {:>2} {:>7} {:>9}{} {:>9} {:>8} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7} "
      "{:>7} {:>9} {:>7}{}{}{} {}\n",
      "backend", rates ? fmt::format(" {:>7}", "rate") : "", "vertices", "B", "frames", "frames/s",
      characters ? fmt::format(" {:>9}", "chars/s") : "", "Mvert/s", "MB/s", "p50 ms", "p90 ms",
      "p99 ms", "max ms", fmt::format("p{:g} ms", percentile), "queue", "compute", "encode",
      "transport", "speedup",
      open_loop ? fmt::format(" {:>6} {:>7} {:>10}", "late", "dropped", "late sends") : "",
      trials ? fmt::format(" {:>6}", "stable") : "", cpu ? ServerCpuHeader() : "", "errors");
  for (const RunResult& r : results) {
    const LatencySummary l = Summarize(r.latencies_ms, r.percentile);
    const double serial = SerialFramesPerSecond(results, r);
    fmt::print(
        "{:<16}{} {:>8} {:>2} {:>7} {:>9.1f}{} {:>9.1f} {:>8.1f} {:>7.2f} {:>7.2f} {:>7.2f} "
        "{:>7.2f} {:>7.2f} {:>7.2f} {:>7.2f} {:>7.2f} {:>9.2f} {:>7}{}{}{} {}{}{}\n",
        BackendLabel(r), rates ? fmt::format(" {:>7g}", r.rate) : "", r.vertices, r.bones, r.frames,
        r.frames_per_second(),
        characters ? fmt::format(" {:>9.1f}", r.characters_per_second()) : "",
        r.vertices_per_second() / 1e6, r.megabytes_per_second(), l.p50, l.p90, l.p99, l.max,
        l.at_percentile, r.mean(r.server_queue_ms_sum), r.mean(r.server_compute_ms_sum),
        r.mean(r.server_encode_ms_sum), r.mean(r.transport_ms_sum),
        serial > 0 ? fmt::format("{:.2f}x", r.frames_per_second() / serial) : "-",
        open_loop ? fmt::format(" {:>6} {:>7} {:>10}", r.late, r.dropped, r.late_sends) : "",
        trials ? fmt::format(" {:>6}", !r.stable   ? "-"
                                       : *r.stable ? "yes"
                                                   : "no")
               : "",
        cpu ? ServerCpuCells(r) : "", ErrorsText(r),
        r.mismatches > 0 ? fmt::format(" MISMATCHES={}", r.mismatches) : "",
        r.within_limit() ? "" : " OVER-LIMIT");
  }
  PrintErrorExamples(results);
}

void PrintSpeedupTables(const std::vector<RunResult>& results) {
  std::vector<std::string> backends;
  std::set<uint32_t> vertices, bones;
  for (const RunResult& r : results) {
    if (std::find(backends.begin(), backends.end(), r.backend) == backends.end()) {
      backends.push_back(r.backend);
    }
    vertices.insert(r.vertices);
    bones.insert(r.bones);
  }
  fmt::print("\n== Speedup over serial through the service (frames/s ratio, same run) ==\n");
  for (const std::string& backend : backends) {
    fmt::print("\n{}\n{:>10}", backend, "vertices");
    for (uint32_t b : bones) fmt::print(" {:>8}", fmt::format("B={}", b));
    fmt::print("\n");
    for (uint32_t v : vertices) {
      fmt::print("{:>10}", v);
      for (uint32_t b : bones) {
        std::string cell = "-";
        for (const RunResult& r : results) {
          if (r.backend != backend || r.vertices != v || r.bones != b) continue;
          const double serial = SerialFramesPerSecond(results, r);
          if (serial > 0) cell = fmt::format("{:.2f}x", r.frames_per_second() / serial);
        }
        fmt::print(" {:>8}", cell);
      }
      fmt::print("\n");
    }
  }
}

Status WriteJson(const std::string& path, const std::vector<RunResult>& results) {
  nlohmann::json doc;
  doc["results"] = nlohmann::json::array();
  for (const RunResult& r : results) doc["results"].push_back(JsonRow(r, results));
  std::ofstream out(path);
  out << doc.dump(2) << "\n";
  if (!out) return InvalidArgument(fmt::format("--json: cannot write {}", path));
  return Status::Ok();
}

Status WriteCsv(const std::string& path, const std::vector<RunResult>& results) {
  std::ofstream out(path);
  const auto& columns = ReportColumns();
  for (std::size_t c = 0; c < columns.size(); ++c) {
    out << (c ? "," : "") << CsvColumnName(columns[c].path);
  }
  out << "\n";
  for (const RunResult& r : results) {
    for (std::size_t c = 0; c < columns.size(); ++c) {
      out << (c ? "," : "") << CsvCell(columns[c].value(r, results));
    }
    out << "\n";
  }
  if (!out) return InvalidArgument(fmt::format("--csv: cannot write {}", path));
  return Status::Ok();
}

std::string SpeedupPlotPath(const std::string& plot_path) {
  std::string path = plot_path;
  const auto dot = path.rfind('.');
  const auto slash = path.rfind('/');
  const bool has_extension =
      dot != std::string::npos && (slash == std::string::npos || dot > slash);
  path.insert(has_extension ? dot : path.size(), "-speedup");
  return path;
}

namespace {

// What a plot shows: the workloads (vertices, bones) and the backends in the order they ran.
struct PlotAxes {
  explicit PlotAxes(const std::vector<RunResult>& rows) : results(rows) {
    for (const RunResult& r : rows) {
      workloads.insert({r.vertices, r.bones});
      if (std::find(backends.begin(), backends.end(), r.backend) == backends.end()) {
        backends.push_back(r.backend);
      }
    }
  }
  const RunResult* Find(const std::string& backend, uint32_t v, uint32_t b) const {
    for (const RunResult& r : results) {
      if (r.backend == backend && r.vertices == v && r.bones == b) return &r;
    }
    return nullptr;
  }

  const std::vector<RunResult>& results;
  std::set<std::pair<uint32_t, uint32_t>> workloads;
  std::vector<std::string> backends;
};

// Throughput bars: one cluster per workload, one bar per backend. A sweep spans two orders
// of magnitude of frames/s, hence the log scale there.
std::string ThroughputPlot(const PlotAxes& axes, const std::string& path,
                           const std::string& data_path) {
  {
    std::ofstream data(data_path);
    data << "workload";
    for (const std::string& backend : axes.backends) data << " \"" << backend << "\"";
    data << "\n";
    for (const auto& [v, b] : axes.workloads) {
      data << fmt::format("\"{}k/{}\"", v / 1000, b);
      for (const std::string& backend : axes.backends) {
        const RunResult* r = axes.Find(backend, v, b);
        data << fmt::format(" {:.3f}", r != nullptr ? r->frames_per_second() : 0.0);
      }
      data << "\n";
    }
  }
  const bool sweep = axes.workloads.size() > 1;
  return fmt::format(
      "set terminal pngcairo size 1200,700 font ',10'\nset output '{}'\n"
      "set title 'skinserve: frames per second through the service, per workload "
      "(vertices/bones; higher is better)'\n"
      "set style data histograms\nset style histogram clustered gap 1\n"
      "set style fill solid 0.85 border -1\nset ylabel 'frames/s{}'\n{}\nset grid ytics\n"
      "set key outside right top\n"
      "plot for [i=2:{}] '{}' using i:xtic(1) title columnheader(i)\n",
      path, sweep ? " (log scale)" : "", sweep ? "set logscale y" : "set yrange [0:*]",
      axes.backends.size() + 1, data_path);
}

// The sweep's heat map: backends x (vertices, bones), colour = speedup over serial.
std::string SpeedupPlot(const PlotAxes& axes, const std::string& path,
                        const std::string& heat_data) {
  std::ofstream heat(heat_data);
  std::string xtics, ytics;
  int x = 0;
  for (const auto& [v, b] : axes.workloads) {
    xtics += fmt::format("{}\"{}k/{}\" {}", x ? ", " : "", v / 1000, b, x);
    for (std::size_t y = 0; y < axes.backends.size(); ++y) {
      if (const RunResult* r = axes.Find(axes.backends[y], v, b)) {
        const double serial = SerialFramesPerSecond(axes.results, *r);
        heat << fmt::format("{} {} {:.3f}\n", x, y,
                            serial > 0 ? r->frames_per_second() / serial : 0);
      }
    }
    ++x;
  }
  for (std::size_t y = 0; y < axes.backends.size(); ++y) {
    ytics += fmt::format("{}\"{}\" {}", y ? ", " : "", axes.backends[y], y);
  }
  return fmt::format(
      "reset\nset terminal pngcairo size 1200,700 font ',10'\nset output '{}'\n"
      "set title 'speedup over serial through the service (vertices/bones)'\n"
      "set xtics ({}) rotate by -45\nset ytics ({})\nset cblabel 'x serial'\n"
      "set palette rgbformulae 33,13,10\nset view map\nset xrange [-0.5:{}]\n"
      "set yrange [-0.5:{}]\nunset key\nplot '{}' using 1:2:3 with image, '' using "
      "1:2:(sprintf('%.1f',$3)) with labels font ',8'\n",
      SpeedupPlotPath(path), xtics, ytics, x - 0.5, axes.backends.size() - 0.5, heat_data);
}

}  // namespace

Status WritePlot(const std::string& path, const std::vector<RunResult>& results) {
  if (system("command -v gnuplot >/dev/null 2>&1") != 0) {
    return FailedPrecondition("--plot needs gnuplot (Debian package gnuplot-nox)");
  }
  char data_path[] = "/tmp/skinserve-plot-XXXXXX";
  const int fd = mkstemp(data_path);
  if (fd < 0) return Internal("--plot: cannot create a temporary file");
  close(fd);
  const PlotAxes axes(results);
  std::string script = ThroughputPlot(axes, path, data_path);
  std::string heat_data;
  if (axes.workloads.size() > 1) {
    heat_data = std::string(data_path) + "-heat";
    script += SpeedupPlot(axes, path, heat_data);
  }
  FILE* gnuplot = popen("gnuplot", "w");
  if (gnuplot == nullptr) return Internal("--plot: cannot run gnuplot");
  fputs(script.c_str(), gnuplot);
  const int code = pclose(gnuplot);
  std::remove(data_path);
  if (!heat_data.empty()) std::remove(heat_data.c_str());
  if (code != 0) return Internal(fmt::format("--plot: gnuplot failed ({})", code));
  return Status::Ok();
}

}  // namespace skinserve::load
