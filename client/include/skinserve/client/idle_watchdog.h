// IdleWatchdog: cancels a call that waits for an answer longer than its limit. A stream has
// no deadline (it may last for hours), but a stream whose server stopped answering (hung,
// or gone without a FIN while keepalive is off or slower) must not wait for ever: while an
// answer is awaited and none has come for `limit`, the watchdog cancels the call's context
// (its reads end, its status is CANCELLED) and says so in fired().
#pragma once

#include <grpcpp/client_context.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <thread>

namespace skinserve::client {

class IdleWatchdog {
 public:
  // `limit` 0: never fires (and starts no thread).
  IdleWatchdog(grpc::ClientContext* context, std::chrono::milliseconds limit);
  // The same for a connection that is not a gRPC call: `cancel` ends its reads.
  IdleWatchdog(std::function<void()> cancel, std::chrono::milliseconds limit);
  ~IdleWatchdog();
  IdleWatchdog(const IdleWatchdog&) = delete;
  IdleWatchdog& operator=(const IdleWatchdog&) = delete;

  // An answer (or part of one) arrived: the idle clock starts again.
  void Answered() { last_answer_.store(Now(), std::memory_order_relaxed); }
  // Whether an answer is awaited (frames in flight). The clock runs only while one is; it
  // starts when this turns true.
  void Awaiting(bool awaiting);
  bool fired() const { return fired_.load(); }
  std::chrono::milliseconds limit() const { return limit_; }

 private:
  static int64_t Now();
  void Watch();

  const std::function<void()> cancel_;
  const std::chrono::milliseconds limit_;
  std::atomic<int64_t> last_answer_;
  std::atomic<bool> awaiting_{false};
  std::atomic<bool> fired_{false};
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace skinserve::client
