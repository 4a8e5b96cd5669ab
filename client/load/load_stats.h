// The arithmetic of a load run: percentiles, rates and means, kept apart from the I/O so
// that it is unit-tested against hand-computed values.
#pragma once

#include <algorithm>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "skinserve/model/status.h"

namespace skinserve::load {

// The q-quantile (0..1) of `values` by linear interpolation between closest ranks
// (numpy's default); 0 for no values. Sorts `values`.
double Percentile(std::vector<double>& values, double q);

struct LatencySummary {
  double p50 = 0, p90 = 0, p99 = 0, max = 0;
  double at_percentile = 0;  // at Summarize's `percentile`
};
// `percentile` in 0..100 (--percentile): the latency limit's and the headline's.
LatencySummary Summarize(std::vector<double> latencies_ms, double percentile = 99);

// What one backend delivered on one workload.
struct RunResult {
  std::string backend;
  uint32_t vertices = 0;
  uint32_t bones = 0;
  bool normals = false;
  bool tangents = false;
  std::string encoding = "float32";
  std::string rest_encoding = "float32";  // the mesh as stored (--rest-encoding)
  uint32_t instances = 1;                 // instances per character (crowd batch)
  // Ticks (--characters-per-tick): characters per request, each its own mesh; 0: plain
  // frames, one character per request. A tick is one "frame" of this row: frames, latency
  // and frames_per_second count ticks, the character columns count characters.
  uint32_t characters_per_tick = 0;
  std::string data_plane = "grpc";  // or "shm": vertices written into shared memory
  bool pose = false;                // --animate: posed on the server from a clip, not a palette
  std::string clip;                 // --animate: "synthetic", or the glTF clip's name
  int streams = 0;
  double rate = 0;      // frames/s per stream (open loop); 0: closed loop
  uint64_t frames = 0;  // answered correctly within the measured window
  double seconds = 0;   // the measured window
  std::vector<double> latencies_ms;
  double server_queue_ms_sum = 0, server_compute_ms_sum = 0, server_encode_ms_sum = 0;
  std::map<std::string, uint64_t> errors;  // by gRPC status code name
  // By code: the first error's message, so that a report says why, not only how often.
  std::map<std::string, std::string> error_examples;
  void CountError(const Status& status, uint64_t n = 1);
  uint64_t checked = 0;  // frames compared with the float64 reference
  uint64_t mismatches = 0;
  uint64_t sent = 0;     // frames sent in the measured part (open loop: on schedule)
  uint64_t late = 0;     // open loop: answered after their deadline
  uint64_t dropped = 0;  // open loop: not sent (window full at their time)
  // Open loop: how sends kept to their schedule. A send is late when it left more than
  // kLateSendMs after its scheduled time (the sender overslept, or the machine was busy).
  std::string arrivals;  // constant or poisson; empty in closed loop
  uint64_t late_sends = 0;
  double send_lag_ms_sum = 0;  // sent minus scheduled, over measured answered frames
  // Gaps between one stream's consecutive measured sends, pooled over streams: their mean
  // and coefficient of variation tell the arrivals actually sent (about 1 for Poisson).
  uint64_t send_gaps = 0;
  double send_gap_ms_sum = 0, send_gap_ms_sq_sum = 0;
  // The latency breakdown per answered frame: send lag + queue + skinning + encode +
  // transport = the client's latency. The server's compute includes encoding (an encoded
  // frame is encoded right after skinning), so skinning = compute - encode, the encode
  // capped at compute (summed over a crowd's instances it may exceed compute's wall time).
  double skinning_ms_sum = 0, breakdown_encode_ms_sum = 0, transport_ms_sum = 0;
  double percentile = 99;  // --percentile: which the headline latency and the limit use
  std::optional<double> latency_limit_ms;  // --latency-limit-ms, when given
  int trials = 1;                          // measurement windows run (--max-trials)
  std::optional<bool> stable;              // the stability rule's verdict; none when not applied
  // --metrics-url: the server's counter deltas over this row's windows, by series.
  bool metrics_scraped = false;
  std::map<std::string, double> server_metrics;
  // --metrics-url: the increase of the server's process_cpu_seconds_total (the whole
  // process's user + system CPU) over the measured part; none when not scraped, when the
  // server does not export it, or when it went down (the server restarted). And the frames
  // the server answered between the same two scrapes (skinserve_frames_total, every
  // backend): both from one pair of scrapes, however late either answered.
  std::optional<double> server_cpu_seconds;
  double server_frames = 0;
  // The requests (frames or ticks) server_frames stands for.
  double server_requests() const {
    return characters_per_tick > 0 ? server_frames / characters_per_tick : server_frames;
  }

  // The latency at `percentile` within the limit (true when no limit).
  bool within_limit() const;

  double frames_per_second() const { return seconds > 0 ? frames / seconds : 0; }
  // Characters a request carries: a tick's characters times each one's crowd.
  uint32_t characters_per_frame() const {
    return std::max(characters_per_tick, 1u) * std::max(instances, 1u);
  }
  double characters_per_second() const { return frames_per_second() * characters_per_frame(); }
  // Every character's vertices.
  double vertices_per_second() const { return characters_per_second() * vertices; }
  // Vertex payload returned, in MB/s (12 bytes per vertex in float32, 6 in float16 and
  // snorm16; twice that with normals; tangents add 4 values a vertex).
  double megabytes_per_second() const {
    const double per_value = encoding == "float32" ? 4.0 : 2.0;
    return vertices_per_second() * per_value * (3 + (normals ? 3 : 0) + (tangents ? 4 : 0)) / 1e6;
  }
  double mean(double sum) const { return frames > 0 ? sum / frames : 0; }
  uint64_t error_count() const;
  // Server CPU per frame it answered and per character (a crowd frame of K instances is K
  // characters; a tick of N characters N x K), in microseconds, and its ratio to the mean
  // compute per frame (ServerTiming's compute_ns, the compute column; a tick's is the sum of
  // its characters'); none without server_cpu_seconds or server_frames (or compute). The
  // server counts each character of a tick as one frame of its backend
  // (skinserve_frames_total), so a tick row's server_frames counts characters.
  std::optional<double> server_cpu_us_per_frame() const;
  std::optional<double> server_cpu_us_per_character() const;
  std::optional<double> server_cpu_over_compute() const;
  double send_gap_mean_ms() const { return send_gaps > 0 ? send_gap_ms_sum / send_gaps : 0; }
  double send_gap_cv() const;
  bool failed() const { return error_count() > 0 || mismatches > 0; }
};

inline constexpr double kLateSendMs = 1.0;

// One row from several measurement windows of one configuration: counts and sums added,
// latencies pooled, seconds summed, metric deltas added (server CPU only when every window
// has it). `windows` must not be empty.
RunResult MergeResults(const std::vector<RunResult>& windows);

}  // namespace skinserve::load
