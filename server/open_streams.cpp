#include "open_streams.h"

#include <vector>

#include "stream_skin_reactor.h"

namespace skinserve::server {

bool OpenStreams::Add(StreamSkinReactor* stream) {
  std::lock_guard lock(mutex_);
  if (draining_) return false;
  streams_.insert(stream);
  return true;
}

void OpenStreams::Remove(StreamSkinReactor* stream) {
  std::lock_guard lock(mutex_);
  streams_.erase(stream);
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

std::size_t OpenStreams::count() const {
  std::lock_guard lock(mutex_);
  return streams_.size();
}

}  // namespace skinserve::server
