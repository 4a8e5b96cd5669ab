#include "rpc/open_streams.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <vector>

#include "rpc/stream_skin_reactor.h"

namespace skinserve::server {

OpenStreams::OpenStreams(const StreamLimits& limits)
    : limits_(limits),
      // At most 1e9 s (31 years), so that the limit, and now less it, stay in range.
      idle_limit_(std::chrono::duration_cast<std::chrono::nanoseconds>(
          std::chrono::duration<double>(std::min(limits.idle_seconds, 1e9)))),
      watchdog_([this] { Watch(); }) {}

OpenStreams::~OpenStreams() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  watchdog_.join();
}

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

void OpenStreams::Watch() {
  // A quarter of the limit, at most 250 ms: a quiet stream ends at most a quarter late.
  const auto period = std::clamp<std::chrono::nanoseconds>(
      idle_limit_ / 4, std::chrono::milliseconds(1), std::chrono::milliseconds(250));
  const std::string why = fmt::format(
      "this stream sent no frame for {} s with none in flight, the server's limit "
      "(--stream-idle-seconds {}), and was ended",
      limits_.idle_seconds, limits_.idle_seconds);
  std::unique_lock lock(mutex_);
  while (!wake_.wait_for(lock, period, [&] { return stopping_; })) {
    const auto cutoff = std::chrono::steady_clock::now() - idle_limit_;
    // As in DrainAll: held, and ended outside our lock.
    std::vector<StreamSkinReactor*> quiet;
    for (StreamSkinReactor* stream : streams_) {
      if (stream->quiet_since() <= cutoff) {
        stream->Hold();
        quiet.push_back(stream);
      }
    }
    if (quiet.empty()) continue;
    lock.unlock();
    uint64_t ended = 0;
    for (StreamSkinReactor* stream : quiet) {
      if (stream->EndIfQuietSince(cutoff, why)) ++ended;
      stream->Release();
    }
    if (ended > 0) spdlog::debug("{} idle streams ended (--stream-idle-seconds)", ended);
    lock.lock();
    ended_idle_ += ended;
  }
}

}  // namespace skinserve::server
