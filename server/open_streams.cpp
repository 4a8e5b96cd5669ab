#include "open_streams.h"

#include <fmt/format.h>

#include <vector>

#include "stream_skin_reactor.h"

namespace skinserve::server {

Status OpenStreams::Add(StreamSkinReactor* stream) {
  std::lock_guard lock(mutex_);
  if (draining_) return Unavailable("the server is shutting down; use another replica");
  if (streams_.size() >= limit_) {
    return ResourceExhausted(fmt::format(
        "the server has {} StreamSkin streams open, its limit (--max-streams {}); retry "
        "later or on another replica",
        streams_.size(), limit_));
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

}  // namespace skinserve::server
