// FrameSocketConnection: one client of the frame socket (frame_socket.h), served on a
// thread of its own, one request at a time in the order sent. A request is read (its size
// checked against the limits and its bytes charged to the in-flight budget before they are
// read, then SkinRequestReader's scan and charge before the parse), prepared with the
// connection's StreamPlan exactly as StreamSkin prepares it (FrameJob, TickJob), and run by
// Engine::Run on this thread when a compute thread is free (ComputePool::TryRunInline), so
// a small frame is read, skinned and answered by one thread that sleeps only in recv. Its
// answer parts are written straight from the job's buffers (sendmsg over the slices). A
// frame that fails is answered with its error and the connection goes on; the connection
// ends (with a last message saying why, wire/frame_socket_protocol.h) when the client
// half-closes, breaks the protocol, sends a request over the limits, stays quiet for
// --stream-idle-seconds, or the server drains.
#pragma once

#include <sys/uio.h>

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "frames/frame_job.h"
#include "frames/skin_request_reader.h"
#include "frames/stream_plan.h"
#include "frames/tick_job.h"
#include "socket/frame_socket_access.h"

namespace skinserve::server {

class FrameSocketConnection final : private FrameJob::Listener {
 public:
  // Takes `fd` (a connected Unix stream socket; closed by the destructor).
  FrameSocketConnection(int fd, FrameSocketAccess access, double idle_seconds);
  ~FrameSocketConnection();
  FrameSocketConnection(const FrameSocketConnection&) = delete;
  FrameSocketConnection& operator=(const FrameSocketConnection&) = delete;

  // Serves the connection until it ends; then sends the last message and returns.
  void Serve();
  // From another thread: the connection ends UNAVAILABLE once the request being served is
  // answered (a blocked read returns at once).
  void Drain();
  // Ends the connection with `status` as its last message, without serving it (a
  // connection over the server's limit).
  void Refuse(const Status& status);
  FrameSocketCounters* counters() const { return access_.counters; }

 private:
  // None: go on; else the connection ends, its last message carrying the status (none is
  // sent once the client is gone: client_gone_).
  using End = std::optional<Status>;
  End ServeOne();
  // Reads until `bytes` are buffered from read_begin_, growing the buffer (charged to the
  // budget first). The end when the client half-closed (OK if `at_boundary`: nothing of a
  // message was read), stayed quiet too long, the server drains, or the budget refuses.
  End Fill(std::size_t bytes, bool at_boundary);
  End Grow(std::size_t bytes);
  // Answers the request in the buffer's [read_begin_, read_begin_ + size): a frame or a tick.
  End Answer(std::size_t size);
  // Waits for `answer` to be done, then writes its parts; none if the client went away.
  End WriteAnswer(StreamAnswer& answer);
  bool WriteMessage(const grpc::ByteBuffer& message, bool end);
  void SendEnd(const Status& status);
  std::string QuietOrDrained(const char* what) const;

  void OnFrameDone(StreamAnswer* job) override;
  void OnPartsReady(StreamAnswer*) override {}  // parts go out once the answer is done
  void HoldForWire() override {}                // the wire is this thread's: written in place
  void ReleaseForWire() override {}

  const int fd_;
  bool client_gone_ = false;  // a write failed: nothing more can be delivered
  const FrameSocketAccess access_;
  const double idle_seconds_;
  const int idle_ms_;  // the same, for poll
  std::atomic<bool> draining_{false};
  SkinRequestReader reader_;
  StreamPlan plan_;
  std::unique_ptr<FrameJob> job_;  // reused frame after frame
  TickJobs ticks_;
  std::optional<uint64_t> last_frame_read_;

  // Received bytes: [read_begin_, read_end_) not consumed yet; charged_ of the budget.
  std::vector<std::byte> buffer_;
  std::size_t read_begin_ = 0, read_end_ = 0;
  uint64_t charged_ = 0;

  // WriteMessage's: a part's slices and the iovecs over them, capacity kept frame to frame.
  std::vector<grpc::Slice> slices_;
  std::vector<iovec> iov_;

  std::mutex mutex_;
  std::condition_variable answered_;
};

}  // namespace skinserve::server
