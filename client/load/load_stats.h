// The arithmetic of a load run: percentiles, rates and means, kept apart from the I/O so
// that it is unit-tested against hand-computed values.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace skinserve::load {

// The q-quantile (0..1) of `values` by linear interpolation between closest ranks
// (numpy's default); 0 for no values. Sorts `values`.
double Percentile(std::vector<double>& values, double q);

struct LatencySummary {
  double p50 = 0, p90 = 0, p99 = 0, max = 0;
};
LatencySummary Summarize(std::vector<double> latencies_ms);

// What one backend delivered on one workload.
struct RunResult {
  std::string backend;
  uint32_t vertices = 0;
  uint32_t bones = 0;
  bool normals = false;
  std::string encoding = "float32";
  uint32_t instances = 1;           // characters per frame (crowd batch)
  std::string data_plane = "grpc";  // or "shm": vertices written into shared memory
  int streams = 0;
  double rate = 0;      // frames/s per stream (open loop); 0: closed loop
  uint64_t frames = 0;  // answered correctly within the measured window
  double seconds = 0;   // the measured window
  std::vector<double> latencies_ms;
  double server_queue_ms_sum = 0, server_compute_ms_sum = 0, server_encode_ms_sum = 0;
  std::map<std::string, uint64_t> errors;  // by gRPC status code name
  uint64_t checked = 0;                    // frames compared with the float64 reference
  uint64_t mismatches = 0;
  uint64_t sent = 0;     // frames sent in the measured part (open loop: on schedule)
  uint64_t late = 0;     // open loop: answered after their deadline
  uint64_t dropped = 0;  // open loop: not sent (window full at their time)

  double frames_per_second() const { return seconds > 0 ? frames / seconds : 0; }
  // Every instance's vertices.
  double vertices_per_second() const { return frames_per_second() * vertices * instances; }
  // Vertex payload returned, in MB/s (12 bytes per vertex in float32, 6 in float16 and
  // snorm16; twice that with normals).
  double megabytes_per_second() const {
    const double per_vertex = encoding == "float32" ? 12.0 : 6.0;
    return vertices_per_second() * per_vertex * (normals ? 2 : 1) / 1e6;
  }
  double mean(double sum) const { return frames > 0 ? sum / frames : 0; }
  uint64_t error_count() const;
  bool failed() const { return error_count() > 0 || mismatches > 0; }
};

}  // namespace skinserve::load
