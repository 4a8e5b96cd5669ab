#include "compute_pool.h"

#include <algorithm>

namespace skinserve {

ComputePool::ComputePool(int threads, std::size_t capacity, uint64_t split_min_work)
    : capacity_(std::max<std::size_t>(capacity, 1)),
      split_min_work_(std::max<uint64_t>(split_min_work, 1)),
      ring_(capacity_) {
  threads = std::max(threads, 1);
  free_threads_ = threads;
  workers_.reserve(threads);
  for (int i = 0; i < threads; ++i) workers_.emplace_back([this] { WorkerLoop(); });
}

ComputePool::~ComputePool() { Shutdown(); }

bool ComputePool::TrySubmit(const Task& task) {
  {
    std::lock_guard lock(mutex_);
    if (stopping_ || count_ >= capacity_) return false;
    Task& slot = ring_[(head_ + count_) % capacity_];
    slot = task;
    slot.parts = std::max<uint32_t>(slot.parts, 1);
    slot.min_width = std::clamp(slot.min_width, 1, size());
    slot.max_width = std::clamp(slot.max_width, slot.min_width, size());
    ++count_;
  }
  // Every idle thread could take it, and one is enough: a part it leaves for others (a
  // crowd's next instance) wakes the next thread then.
  changed_.notify_one();
  return true;
}

bool ComputePool::TryRunInline(const Task& task) {
  if (task.parts > 1 || task.min_width > 1 || task.work >= split_min_work_) return false;
  {
    std::lock_guard lock(mutex_);
    if (stopping_ || count_ > 0 || free_threads_ < 1) return false;
    --free_threads_;
    ++inline_runs_;
    peak_busy_ = std::max(peak_busy_, size() - free_threads_);
  }
  task.run(task.context, 0, 1);
  {
    std::lock_guard lock(mutex_);
    ++free_threads_;
    if (count_ == 0) return true;  // nobody waited for the thread it held
  }
  changed_.notify_all();
  return true;
}

bool ComputePool::TrySubmit(int width, std::function<void()> task) {
  auto* owned = new std::function<void()>(std::move(task));
  Task wrapped;
  wrapped.run = [](void* context, uint32_t, int) {
    auto* function = static_cast<std::function<void()>*>(context);
    (*function)();
    delete function;
  };
  wrapped.context = owned;
  wrapped.min_width = wrapped.max_width = width;
  if (TrySubmit(wrapped)) return true;
  delete owned;
  return false;
}

void ComputePool::Shutdown() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  changed_.notify_all();
  std::call_once(joined_, [this] {
    for (auto& worker : workers_) worker.join();
  });
}

std::size_t ComputePool::depth() const {
  std::lock_guard lock(mutex_);
  return count_;
}

int ComputePool::peak_busy() const {
  std::lock_guard lock(mutex_);
  return peak_busy_;
}

uint64_t ComputePool::inline_runs() const {
  std::lock_guard lock(mutex_);
  return inline_runs_;
}

int ComputePool::GrantLocked() const {
  const Task& head = ring_[head_];
  if (free_threads_ < head.min_width) return 0;
  // Anything else waiting (another part of this task or another task) gets the other
  // threads: side by side beats splitting, and nothing is woken that would then wait.
  const bool others_wait = next_part_ + 1 < head.parts || count_ > 1;
  if (head.max_width == head.min_width || others_wait) return head.min_width;
  // Split, but keep one thread free for the frames that arrive meanwhile: a large frame
  // started on an idle pool must not make every later small frame wait for it.
  const uint64_t worth = std::max<uint64_t>(head.work / split_min_work_, 1);
  const int spare = std::max(free_threads_ - 1, 1);
  const int threads = static_cast<int>(std::min<uint64_t>(worth, spare));
  return std::clamp(threads, head.min_width, head.max_width);
}

void ComputePool::WorkerLoop() {
  std::unique_lock lock(mutex_);
  while (true) {
    // Head of line only: the oldest task's parts start first, once enough threads are free.
    changed_.wait(
        lock, [this] { return (stopping_ && count_ == 0) || (count_ > 0 && GrantLocked() > 0); });
    if (count_ == 0) return;
    const int width = GrantLocked();
    const Task task = ring_[head_];
    const uint32_t part = next_part_++;
    if (next_part_ >= task.parts) {
      head_ = (head_ + 1) % capacity_;
      --count_;
      next_part_ = 0;
    }
    free_threads_ -= width;
    peak_busy_ = std::max(peak_busy_, size() - free_threads_);
    // The next part may fit in the threads still free; with nothing left, waking the idle
    // threads would only put them back to sleep (unless they are to stop).
    if (count_ > 0 || stopping_) changed_.notify_all();
    lock.unlock();
    task.run(task.context, part, width);
    lock.lock();
    free_threads_ += width;
    // A task waiting for more free threads may start now, or the others may stop (this
    // thread looks itself).
    if (count_ > 0 || stopping_) changed_.notify_all();
  }
}

}  // namespace skinserve
