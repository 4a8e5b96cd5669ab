#include "skinserve/client/idle_watchdog.h"

namespace skinserve::client {

IdleWatchdog::IdleWatchdog(grpc::ClientContext* context, std::chrono::milliseconds limit)
    : IdleWatchdog([context] { context->TryCancel(); }, limit) {}

IdleWatchdog::IdleWatchdog(std::function<void()> cancel, std::chrono::milliseconds limit)
    : cancel_(std::move(cancel)), limit_(limit), last_answer_(Now()) {
  if (limit_.count() > 0) thread_ = std::thread([this] { Watch(); });
}

IdleWatchdog::~IdleWatchdog() {
  if (!thread_.joinable()) return;
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_one();
  thread_.join();
}

int64_t IdleWatchdog::Now() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

void IdleWatchdog::Awaiting(bool awaiting) {
  if (awaiting && !awaiting_.load(std::memory_order_relaxed)) Answered();
  awaiting_.store(awaiting, std::memory_order_relaxed);
}

// Wakes once per `limit` at most (at the time the limit would run out), so a busy stream
// costs the watchdog nothing but two relaxed stores per answer.
void IdleWatchdog::Watch() {
  const int64_t limit_ns = std::chrono::nanoseconds(limit_).count();
  std::unique_lock lock(mutex_);
  while (!stop_) {
    const int64_t idle = Now() - last_answer_.load(std::memory_order_relaxed);
    if (awaiting_.load(std::memory_order_relaxed) && idle >= limit_ns) {
      fired_.store(true);
      cancel_();
      return;
    }
    const int64_t wait = awaiting_.load(std::memory_order_relaxed) ? limit_ns - idle : limit_ns;
    wake_.wait_for(lock, std::chrono::nanoseconds(std::max<int64_t>(wait, 1'000'000)),
                   [this] { return stop_; });
  }
}

}  // namespace skinserve::client
