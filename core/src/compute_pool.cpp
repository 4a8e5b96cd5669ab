#include "compute_pool.h"

#include <algorithm>

namespace skinserve {

ComputePool::ComputePool(int threads, std::size_t capacity)
    : capacity_(std::max<std::size_t>(capacity, 1)) {
  threads = std::max(threads, 1);
  free_threads_ = threads;
  workers_.reserve(threads);
  for (int i = 0; i < threads; ++i) workers_.emplace_back([this] { WorkerLoop(); });
}

ComputePool::~ComputePool() { Shutdown(); }

bool ComputePool::TrySubmit(int width, std::function<void()> task) {
  {
    std::lock_guard lock(mutex_);
    if (stopping_ || queue_.size() >= capacity_) return false;
    queue_.push_back({std::clamp(width, 1, size()), std::move(task)});
  }
  changed_.notify_all();
  return true;
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
  return queue_.size();
}

void ComputePool::WorkerLoop() {
  std::unique_lock lock(mutex_);
  while (true) {
    // Head of line only: the oldest task starts first, once enough threads are free.
    changed_.wait(lock, [this] {
      return (stopping_ && queue_.empty()) ||
             (!queue_.empty() && free_threads_ >= queue_.front().width);
    });
    if (queue_.empty()) return;
    Task task = std::move(queue_.front());
    queue_.pop_front();
    free_threads_ -= task.width;
    changed_.notify_all();  // the new head may fit in the threads still free
    lock.unlock();
    task.run();
    lock.lock();
    free_threads_ += task.width;
    changed_.notify_all();
  }
}

}  // namespace skinserve
