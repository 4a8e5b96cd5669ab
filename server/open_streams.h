// OpenStreams: the StreamSkin calls in progress, at most `limit` of them, so that a
// shutdown can drain them. A drained stream stops reading, answers every frame it has
// read and ends with UNAVAILABLE, which tells its client to go on elsewhere at once,
// instead of streaming on through the grace period and then being cancelled.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <mutex>
#include <unordered_set>

#include "skinserve/model/status.h"

namespace skinserve::server {

class StreamSkinReactor;

class OpenStreams {
 public:
  explicit OpenStreams(std::size_t limit) : limit_(limit) {}
  // Registers `stream`. Otherwise the stream should end at once with the status:
  // UNAVAILABLE once draining, RESOURCE_EXHAUSTED (naming the limit) when `limit` are open.
  Status Add(StreamSkinReactor* stream);
  void Remove(StreamSkinReactor* stream);
  // Drains every open stream and refuses new ones. Idempotent.
  void DrainAll();
  // Waits until every stream has ended (its final status sent), or until `deadline`;
  // true if they all ended.
  bool WaitUntilAllEnded(std::chrono::steady_clock::time_point deadline);
  std::size_t count() const;

 private:
  const std::size_t limit_;
  mutable std::mutex mutex_;
  std::condition_variable ended_;  // notified when the last open stream is removed
  std::unordered_set<StreamSkinReactor*> streams_;
  bool draining_ = false;
};

}  // namespace skinserve::server
