// StreamSession: the loop StreamFrames and StreamTicks share. Units (frames or ticks) go
// over StreamSkin with a window in flight: fill the window, read the oldest unit's answer,
// settle it (deliver it, or send it again after a re-upload), and retry on a new stream
// when one breaks. What a unit is (its request, its answer, its re-upload) is a StreamPath.
#pragma once

#include <grpcpp/support/byte_buffer.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <deque>
#include <string_view>
#include <vector>

#include "skinserve/client/skin_client.h"

namespace skinserve::client {

using SessionClock = std::chrono::steady_clock;

// A unit sent and not yet answered.
struct InFlight {
  uint64_t frame = 0;
  SessionClock::time_point sent;
  int uploads_before = 0;  // re-uploads done when it was sent
  std::size_t slot = 0;    // its window slot: units in flight never share one
};

// The units in flight, oldest first: a ring of `window` slots allocated once (a deque
// would allocate and free a block every few dozen units). A unit's slot is its place in
// the ring, so a region's slots follow it.
class InFlightRing {
 public:
  explicit InFlightRing(std::size_t window) : slots_(window) {}
  bool empty() const { return size_ == 0; }
  std::size_t size() const { return size_; }
  // The slot the next push_back takes.
  std::size_t next_slot() const { return (head_ + size_) % slots_.size(); }
  void push_back(const InFlight& f) { slots_[(head_ + size_++) % slots_.size()] = f; }
  const InFlight& front() const { return slots_[head_]; }
  void pop_front() {
    head_ = (head_ + 1) % slots_.size();
    --size_;
  }
  template <typename F>
  void ForEach(F f) const {
    for (std::size_t i = 0; i < size_; ++i) f(slots_[(head_ + i) % slots_.size()]);
  }
  void clear() { head_ = size_ = 0; }

 private:
  std::vector<InFlight> slots_;
  std::size_t head_ = 0, size_ = 0;
};

struct SessionOptions {
  uint64_t first = 0;  // the first unit's frame number
  uint64_t count = 0;  // units to send
  int window = 1;      // units in flight (at least 1)
  int max_reconnects = 3;
  int max_reuploads = 8;
  const std::atomic<bool>* stop = nullptr;  // when true, no new unit is sent
  std::string_view unit = "frame";          // in the session's messages
};

// What StreamFrames and StreamTicks both report.
struct SessionCounts {
  uint64_t sent = 0;      // units written to a stream (resends not counted twice)
  uint64_t answered = 0;  // units settled as answered
  uint64_t failed = 0;    // units settled as failed, or failed with their stream
  uint64_t reconnects = 0;
  uint64_t reuploads = 0;  // re-uploads that went through
};

// The session's options from StreamOptions or TickStreamOptions (the fields they share);
// `first` and `count` number the units.
template <typename Options>
SessionOptions SessionOptionsOf(const Options& o, uint64_t first, uint64_t count,
                                std::string_view unit) {
  return {.first = first,
          .count = count,
          .window = o.window,
          .max_reconnects = o.max_reconnects,
          .max_reuploads = o.max_reuploads,
          .stop = o.stop,
          .unit = unit};
}

// Copies the session's counts into StreamSummary or TickStreamSummary.
template <typename Summary>
void CopyCounts(const SessionCounts& c, Summary* summary) {
  summary->sent = c.sent;
  summary->answered = c.answered;
  summary->failed = c.failed;
  summary->reconnects = c.reconnects;
  summary->reuploads = c.reuploads;
}

class StreamSession;

// What differs between frames and ticks.
class StreamPath {
 public:
  enum class Settled { kResend, kAnswered, kFailed };
  virtual ~StreamPath() = default;
  // Makes unit `frame`'s request for window slot `slot`; not OK ends the session with it.
  virtual Status Prepare(uint64_t frame, std::size_t slot) = 0;
  // The request Prepare made.
  virtual const v1::SkinRequest& request() const = 0;
  // Starts gathering the answer of `head`; AddPart is true once it is complete.
  virtual void BeginAnswer(const InFlight& head) = 0;
  virtual bool AddPart(const grpc::ByteBuffer& part) = 0;
  // `head`'s answer is complete: deliver it (to the sink) or have it sent again, re-uploading
  // what the server lost through the session's re-upload rule.
  virtual Settled Settle(const InFlight& head, StreamSession& session) = 0;
  // `f` failed with its stream (`why`): deliver it failed.
  virtual void Fail(const InFlight& f, const Status& why) = 0;
};

class StreamSession {
 public:
  StreamSession(SkinClient& client, const SessionOptions& options, StreamPath& path);
  // Returns the status of the last stream (OK when every unit was sent and its stream ended
  // cleanly, even if single units failed).
  Status Run();
  const SessionCounts& counts() const { return counts_; }

  // The re-upload rule, for StreamPath::Settle. A unit that lost its mesh and was sent
  // before the last re-upload just goes again; else the mesh goes again first, at most
  // max_reuploads times.
  bool SentBeforeReupload(const InFlight& f) const { return f.uploads_before < reuploads_; }
  bool MayReupload() const { return reuploads_ < options_.max_reuploads; }
  void CountReuploadAttempt() { ++reuploads_; }
  void CountReuploaded() { ++counts_.reuploads; }
  SkinClient& client() { return client_; }

 private:
  struct Attempt;  // one stream

  bool MoreNew() const;
  Status RunStream(bool* go_on);
  Status Fill(Attempt& attempt);
  bool ReadAnswer(Attempt& attempt);
  void SettleHead();
  Status Retry(Attempt& attempt, bool* go_on);

  SkinClient& client_;
  const SessionOptions options_;
  StreamPath& path_;
  const std::size_t window_;
  const uint64_t end_;
  uint64_t next_;
  std::deque<uint64_t> resend_;  // units to send again (after a re-upload or a reconnect)
  InFlightRing in_flight_;
  int reuploads_ = 0;  // re-upload attempts (SentBeforeReupload)
  int reconnects_in_a_row_ = 0;
  uint64_t answered_at_reconnect_ = 0;
  SessionCounts counts_;
  grpc::ByteBuffer bytes_;
};

// Whether a re-upload's outcome leaves the unit worth sending again: it went through, or
// it was lost on its way (UNAVAILABLE) and the next attempt may find the stream's replica.
inline bool WorthResending(const Status& reupload) {
  return reupload.ok() || reupload.code() == StatusCode::kUnavailable;
}

}  // namespace skinserve::client
