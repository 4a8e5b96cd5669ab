// Collects the benchmark results and prints them in the layout of the paper's tables 2
// and 3: per backend, rows of vertex counts, columns of bones, speedup over `serial`
// measured in the same run; then the fastest backend against the memory bandwidth bound.
#pragma once

#include <benchmark/benchmark.h>

#include <map>
#include <string>
#include <tuple>
#include <vector>

namespace skinserve::bench {

class PaperTablesReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override;
  // Prints the tables for the positions-only runs (and the normals runs, if any).
  void PrintTables(const std::vector<std::string>& backends) const;
  // The OpenCL rates (transfers included, and kernel only) as shares of the device's
  // bounds, when the device bandwidth benchmarks ran; BM_SkinQuantized* rows at the bytes of
  // their integer stream.
  void PrintDeviceBounds() const;
  // BM_Skin[Normals]Quantized* rows: bytes per vertex streamed, share of the memory bound
  // (BM_MemoryBandwidth's best repetition) and speed over the float row of the same backend.
  void PrintQuantizedShares() const;

 private:
  // (kind "BM_Skin" or "BM_SkinNormals", backend, vertices, bones) -> vertices per second
  std::map<std::tuple<std::string, std::string, uint32_t, uint32_t>, double> rates_;
  std::map<std::tuple<std::string, std::string, uint32_t, uint32_t>, double> kernel_rates_;
  std::map<std::string, double> device_bounds_;  // BM_Pcie*, BM_DeviceMemoryCopy: bytes/s
  double bandwidth_bytes_per_second_ = 0;
};

}  // namespace skinserve::bench
