// A thread that does one thing every period until it is stopped: the server's watchdogs (idle
// streams and uploads), the region registries' idle reapers and the authorization policy
// file's reloads. Stopping wakes it at once, lets a call in progress finish, and joins it.
#pragma once

#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <thread>

namespace skinserve::server {

class PeriodicThread {
 public:
  // Starts the thread: `tick` runs first one `period` from now, then every `period`, on no lock
  // of this object's (it takes its owner's own).
  PeriodicThread(std::chrono::nanoseconds period, std::function<void()> tick);
  // Stop(). An owner whose destructor undoes what `tick` reads calls Stop() first; else
  // declaring this member last (destroyed first) is enough.
  ~PeriodicThread();
  PeriodicThread(const PeriodicThread&) = delete;
  PeriodicThread& operator=(const PeriodicThread&) = delete;

  // Wakes the thread and joins it; no `tick` runs after it returns. Called by the owner only
  // (not from `tick`); a second call does nothing.
  void Stop();

 private:
  void Run();

  const std::chrono::nanoseconds period_;
  const std::function<void()> tick_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stopping_ = false;
  std::thread thread_;  // last: it starts once the members above are made
};

}  // namespace skinserve::server
