#include "rpc/open_streams.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <vector>

#include "rpc/stream_skin_reactor.h"
#include "threads/watchdog_period.h"

namespace skinserve::server {

OpenStreams::OpenStreams(const StreamLimits& limits)
    : limits_(limits),
      idle_limit_(LimitNanoseconds(limits.idle_seconds)),
      watchdog_(WatchdogPeriod(idle_limit_), [this] { EndQuietStreams(); }) {}

OpenStreams::~OpenStreams() = default;

Status OpenStreams::Add(StreamSkinReactor* stream) {
  std::lock_guard lock(mutex_);
  if (draining_) return Unavailable("the server is shutting down; use another replica");
  if (streams_.size() >= limits_.max_streams) {
    return ResourceExhausted(fmt::format(
        "the server has {} StreamSkin streams open, its limit (--max-streams {}); retry "
        "later or on another replica",
        streams_.size(), limits_.max_streams));
  }
  streams_.insert(stream);
  return Status::Ok();
}

void OpenStreams::Remove(StreamSkinReactor* stream) {
  std::lock_guard lock(mutex_);
  streams_.erase(stream);
  if (streams_.empty()) ended_.notify_all();
}

void OpenStreams::DrainAll() {
  // Each stream is held (so it outlives its OnDone) and drained outside our lock: draining
  // takes the stream's own lock, and its OnDone takes ours.
  std::vector<StreamSkinReactor*> held;
  {
    std::lock_guard lock(mutex_);
    draining_ = true;
    for (StreamSkinReactor* stream : streams_) {
      stream->Hold();
      held.push_back(stream);
    }
  }
  for (StreamSkinReactor* stream : held) {
    stream->Drain();
    stream->Release();
  }
}

bool OpenStreams::WaitUntilAllEnded(std::chrono::steady_clock::time_point deadline) {
  std::unique_lock lock(mutex_);
  return ended_.wait_until(lock, deadline, [&] { return streams_.empty(); });
}

std::size_t OpenStreams::count() const {
  std::lock_guard lock(mutex_);
  return streams_.size();
}

uint64_t OpenStreams::ended_idle() const {
  std::lock_guard lock(mutex_);
  return ended_idle_;
}

void OpenStreams::EndQuietStreams() {
  const auto cutoff = std::chrono::steady_clock::now() - idle_limit_;
  // As in DrainAll: held, and ended outside our lock.
  std::vector<StreamSkinReactor*> quiet;
  {
    std::lock_guard lock(mutex_);
    for (StreamSkinReactor* stream : streams_) {
      if (stream->quiet_since() <= cutoff) {
        stream->Hold();
        quiet.push_back(stream);
      }
    }
  }
  if (quiet.empty()) return;
  const std::string why = fmt::format(
      "this stream sent no frame for {} s with none in flight, the server's limit "
      "(--stream-idle-seconds {}), and was ended",
      limits_.idle_seconds, limits_.idle_seconds);
  uint64_t ended = 0;
  for (StreamSkinReactor* stream : quiet) {
    if (stream->EndIfQuietSince(cutoff, why)) ++ended;
    stream->Release();
  }
  if (ended > 0) spdlog::debug("{} idle streams ended (--stream-idle-seconds)", ended);
  std::lock_guard lock(mutex_);
  ended_idle_ += ended;
}

}  // namespace skinserve::server
