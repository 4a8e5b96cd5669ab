// ComputePool: the engine's compute threads and its bounded FIFO of frames.
// A task declares its width, the threads it occupies while it runs (1 for a serial
// backend, all of them for OpenMP or OpenCL); a task starts only when that many threads
// are free, in arrival order. So the threads doing skinning never exceed the pool's size,
// however many streams submit, and a wide task is never starved by narrow ones.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace skinserve {

class ComputePool {
 public:
  ComputePool(int threads, std::size_t capacity);
  ~ComputePool();  // Shutdown()
  ComputePool(const ComputePool&) = delete;
  ComputePool& operator=(const ComputePool&) = delete;

  // Queues `task`, to run on a pool thread holding `width` threads (clamped to 1..size).
  // Returns false, without queuing, when `capacity` tasks are already waiting or the pool
  // is shut down.
  bool TrySubmit(int width, std::function<void()> task);
  // Stops accepting, runs every queued task, joins the threads. Idempotent.
  void Shutdown();

  int size() const { return static_cast<int>(workers_.size()); }
  std::size_t capacity() const { return capacity_; }
  std::size_t depth() const;

 private:
  struct Task {
    int width;
    std::function<void()> run;
  };
  void WorkerLoop();

  const std::size_t capacity_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<Task> queue_;
  int free_threads_ = 0;
  bool stopping_ = false;
  std::vector<std::thread> workers_;
  std::once_flag joined_;
};

}  // namespace skinserve
