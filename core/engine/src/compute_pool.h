// ComputePool: the engine's compute threads and its bounded FIFO of frames, scheduled for
// serving many streams rather than for one frame's latency.
//
// A task is one frame in `parts` independent pieces (the instances of a crowd; 1 for a
// single frame). Threads hand out the parts of the oldest task first, one part per
// thread, so the frames of several streams (and the instances of a crowd) run side by
// side, one compute thread each. A part that can use several threads (an OpenMP backend:
// max_width > 1) gets more than one only when nothing else waits and the part is large
// enough to pay for waking them (work / split_min_work threads at most), and never the
// last free thread, which stays for the frames arriving meanwhile: no OpenMP team is
// woken for a small frame while other frames wait, and a large frame started on an idle
// pool does not make every later small frame wait for it. A part that needs a fixed number
// of threads (OpenCL: min_width == max_width) waits at the head until they are free, so
// it is never starved by narrow ones, and narrow ones never wait behind more than the
// frames queued before them. The threads doing skinning never exceed the pool's size.
//
// Submitting copies a small Task by value into a preallocated ring: no allocation.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace skinserve {

class ComputePool {
 public:
  struct Task {
    // Runs part `part` of the task on a pool thread that holds `threads` threads.
    void (*run)(void* context, uint32_t part, int threads) = nullptr;
    void* context = nullptr;
    uint32_t parts = 1;
    int min_width = 1;  // threads a part needs (clamped to 1..size)
    int max_width = 1;  // threads a part can use (clamped to min_width..size)
    uint64_t work = 0;  // per part, in units of split_min_work (vertices)
  };

  // `split_min_work`: the least work per thread for which a part is split.
  ComputePool(int threads, std::size_t capacity, uint64_t split_min_work = 1);
  ~ComputePool();  // Shutdown()
  ComputePool(const ComputePool&) = delete;
  ComputePool& operator=(const ComputePool&) = delete;

  // Queues `task`. Returns false, without queuing, when `capacity` tasks are already
  // waiting or the pool is shut down.
  bool TrySubmit(const Task& task);
  // Runs `task` on the calling thread instead of queuing it, when that costs no
  // parallelism: nothing waits, a pool thread is free (the caller takes its place, so the
  // threads skinning never exceed size()), and the task is one part of one thread's width
  // that would not be split (work below split_min_work). Handing such a frame to a pool
  // thread only adds two thread switches (wake it, then wake the caller's side to answer).
  // Returns whether it ran; false: queue it with TrySubmit.
  bool TryRunInline(const Task& task);
  // For tests and tools: one part of fixed `width`, as a std::function (allocates).
  bool TrySubmit(int width, std::function<void()> task);
  // Stops accepting, runs every queued task, joins the threads. Idempotent.
  void Shutdown();

  int size() const { return static_cast<int>(workers_.size()); }
  std::size_t capacity() const { return capacity_; }
  std::size_t depth() const;
  // Highest number of threads ever held by running parts at once (<= size()).
  int peak_busy() const;
  // Tasks run on their caller's thread (TryRunInline).
  uint64_t inline_runs() const;

 private:
  // The threads the head task's next part gets now; 0 if it must wait.
  int GrantLocked() const;
  void WorkerLoop();

  const std::size_t capacity_;
  const uint64_t split_min_work_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::vector<Task> ring_;  // capacity_ slots; queued tasks are [head_, head_ + count_)
  std::size_t head_ = 0;
  std::size_t count_ = 0;
  uint32_t next_part_ = 0;  // of the head task
  int free_threads_ = 0;
  int peak_busy_ = 0;
  uint64_t inline_runs_ = 0;
  bool stopping_ = false;
  std::vector<std::thread> workers_;
  std::once_flag joined_;
};

}  // namespace skinserve
