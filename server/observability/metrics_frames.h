// Per-frame observations for the Prometheus metrics: the time each frame spent waiting,
// computing, encoding and in the server altogether, and the frames that failed, by
// backend and status code. The engine counts frames and vertices itself (EngineStats);
// what only the server sees is recorded here, once per frame, by the frame's FrameRecord.
//
// FrameMetrics is process-wide (one /metrics per process, as Prometheus scrapes it): the
// server enables it when --metrics-listen is set; until then a FrameRecord costs one
// atomic load. It is never destroyed, so a frame ending during exit cannot outlive it.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "skinserve/engine/engine.h"
#include "skinserve/model/status.h"

namespace skinserve::server {

// Cumulative histogram of durations in seconds, Prometheus' layout.
struct DurationHistogram {
  // Upper bounds, seconds: 50 us (a small frame's queue wait) to 2.5 s (a 4M-vertex frame).
  static constexpr std::array<double, 15> kBounds = {0.00005, 0.0001, 0.00025, 0.0005, 0.001,
                                                     0.0025,  0.005,  0.01,    0.025,  0.05,
                                                     0.1,     0.25,   0.5,     1.0,    2.5};
  std::array<uint64_t, kBounds.size()> buckets{};  // per bucket, not yet cumulative
  uint64_t count = 0;
  double sum_seconds = 0;

  void Observe(int64_t ns);
};

struct BackendFrameMetrics {
  DurationHistogram queue, compute, encode, server;  // server: read to last part produced
  std::map<std::string, uint64_t> errors_by_code;    // "NOT_FOUND" -> frames
};

class FrameMetrics {
 public:
  // The process' instance, or null while metrics are off.
  static FrameMetrics* Installed();
  // Turns the process' instance on (idempotent) and returns it.
  static FrameMetrics* Enable();

  // The enabled backends' ids; frames naming any other id are counted as "other", so a
  // client cannot add label values at will.
  void SetBackends(const std::vector<std::string>& ids);

  // A frame answered with its vertices (timing from the engine, encode from the server).
  void ObserveAnswered(const std::string& backend, const FrameTiming& timing, int64_t encode_ns,
                       int64_t server_ns);
  // A frame answered with an error.
  void ObserveFailed(const std::string& backend, StatusCode code, int64_t server_ns);

  // A consistent copy, by backend id.
  std::map<std::string, BackendFrameMetrics> Snapshot() const;

 private:
  BackendFrameMetrics& For(const std::string& backend);  // under mutex_
  mutable std::mutex mutex_;
  std::set<std::string> known_;
  std::map<std::string, BackendFrameMetrics> backends_;
};

// Ticks (SkinRequest.characters) read and the characters they held, refused ones too:
// counted always (an atomic add per tick), shown on /metrics beside the frames.
struct TickCounts {
  uint64_t ticks = 0;
  uint64_t characters = 0;
};
void CountTick(uint64_t characters);
TickCounts TickTotals();

// One frame's record: begun when the server reads the request, ended once with its
// outcome. Cheap when no FrameMetrics is installed.
class FrameRecord {
 public:
  void Begin(const std::string& backend);
  void EndAnswered(const FrameTiming& timing, int64_t encode_ns);
  void EndFailed(StatusCode code);

 private:
  int64_t ElapsedNs() const;
  std::string backend_;
  std::chrono::steady_clock::time_point started_;
  bool open_ = false;
};

}  // namespace skinserve::server
