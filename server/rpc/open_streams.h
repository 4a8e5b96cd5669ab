// OpenStreams: the StreamSkin calls in progress, at most --max-streams of them, so that a
// shutdown can drain them. A drained stream stops reading, answers every frame it has
// read and ends with UNAVAILABLE, which tells its client to go on elsewhere at once,
// instead of streaming on through the grace period and then being cancelled.
// A watchdog ends a stream that is quiet (no frame in flight, none read) for
// --stream-idle-seconds, so silent clients hold no stream slot for longer: UNAVAILABLE,
// like a drain, since every frame it sent was answered and a new stream may carry on.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <unordered_set>

#include "skinserve/model/status.h"
#include "threads/periodic_thread.h"

namespace skinserve::server {

class StreamSkinReactor;

struct StreamLimits {
  std::size_t max_streams = 1024;
  double idle_seconds = 120;
};

class OpenStreams {
 public:
  explicit OpenStreams(const StreamLimits& limits);
  ~OpenStreams();  // stops the watchdog; every stream has ended by then
  OpenStreams(const OpenStreams&) = delete;
  OpenStreams& operator=(const OpenStreams&) = delete;

  // Registers `stream`. Otherwise the stream should end at once with the status:
  // UNAVAILABLE once draining, RESOURCE_EXHAUSTED (naming the limit) when max_streams are
  // open.
  Status Add(StreamSkinReactor* stream);
  void Remove(StreamSkinReactor* stream);
  // Drains every open stream and refuses new ones. Idempotent.
  void DrainAll();
  // Waits until every stream has ended (its final status sent), or until `deadline`;
  // true if they all ended.
  bool WaitUntilAllEnded(std::chrono::steady_clock::time_point deadline);
  std::size_t count() const;
  // Streams the watchdog ended for --stream-idle-seconds.
  uint64_t ended_idle() const;

 private:
  void EndQuietStreams();  // the watchdog's round

  const StreamLimits limits_;
  const std::chrono::nanoseconds idle_limit_;
  mutable std::mutex mutex_;
  std::condition_variable ended_;  // notified when the last open stream is removed
  std::unordered_set<StreamSkinReactor*> streams_;
  bool draining_ = false;
  uint64_t ended_idle_ = 0;
  PeriodicThread watchdog_;  // last: it uses every member above, and stops first
};

}  // namespace skinserve::server
