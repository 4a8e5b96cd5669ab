#include "observability/metrics_frames.h"

#include <algorithm>
#include <atomic>

namespace skinserve::server {

namespace {
std::atomic<FrameMetrics*> installed{nullptr};
std::atomic<uint64_t> ticks_read{0};
std::atomic<uint64_t> tick_characters_read{0};
}  // namespace

void CountTick(uint64_t characters) {
  ticks_read.fetch_add(1, std::memory_order_relaxed);
  tick_characters_read.fetch_add(characters, std::memory_order_relaxed);
}

TickCounts TickTotals() {
  return {ticks_read.load(std::memory_order_relaxed),
          tick_characters_read.load(std::memory_order_relaxed)};
}

void DurationHistogram::Observe(int64_t ns) {
  const double seconds = static_cast<double>(std::max<int64_t>(ns, 0)) * 1e-9;
  const auto bucket = std::lower_bound(kBounds.begin(), kBounds.end(), seconds);
  if (bucket != kBounds.end()) ++buckets[static_cast<std::size_t>(bucket - kBounds.begin())];
  ++count;  // beyond the last bound: only in +Inf, which is `count`
  sum_seconds += seconds;
}

FrameMetrics* FrameMetrics::Installed() { return installed.load(std::memory_order_acquire); }

FrameMetrics* FrameMetrics::Enable() {
  static FrameMetrics* const instance = new FrameMetrics();  // never destroyed: see header
  installed.store(instance, std::memory_order_release);
  return instance;
}

void FrameMetrics::SetBackends(const std::vector<std::string>& ids) {
  std::lock_guard lock(mutex_);
  known_.insert(ids.begin(), ids.end());
}

BackendFrameMetrics& FrameMetrics::For(const std::string& backend) {
  return backends_[known_.contains(backend) ? backend : std::string("other")];
}

void FrameMetrics::ObserveAnswered(const std::string& backend, const FrameTiming& timing,
                                   int64_t encode_ns, int64_t server_ns) {
  std::lock_guard lock(mutex_);
  BackendFrameMetrics& b = For(backend);
  b.queue.Observe(timing.queued_ns);
  b.compute.Observe(timing.compute_ns);
  b.encode.Observe(encode_ns);
  b.server.Observe(server_ns);
}

void FrameMetrics::ObserveFailed(const std::string& backend, StatusCode code, int64_t server_ns) {
  std::lock_guard lock(mutex_);
  BackendFrameMetrics& b = For(backend);
  ++b.errors_by_code[StatusCodeName(code)];
  b.server.Observe(server_ns);
}

std::map<std::string, BackendFrameMetrics> FrameMetrics::Snapshot() const {
  std::lock_guard lock(mutex_);
  return backends_;
}

void FrameRecord::Begin(const std::string& backend) {
  if (FrameMetrics::Installed() == nullptr) return;  // metrics off: no copy, no clock
  backend_ = backend;
  started_ = std::chrono::steady_clock::now();
  open_ = true;
}

int64_t FrameRecord::ElapsedNs() const {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() -
                                                              started_)
      .count();
}

void FrameRecord::EndAnswered(const FrameTiming& timing, int64_t encode_ns) {
  FrameMetrics* metrics = FrameMetrics::Installed();
  if (!open_ || metrics == nullptr) return;
  open_ = false;
  metrics->ObserveAnswered(backend_, timing, encode_ns, ElapsedNs());
}

void FrameRecord::EndFailed(StatusCode code) {
  FrameMetrics* metrics = FrameMetrics::Installed();
  if (!open_ || metrics == nullptr) return;
  open_ = false;
  metrics->ObserveFailed(backend_, code, ElapsedNs());
}

}  // namespace skinserve::server
