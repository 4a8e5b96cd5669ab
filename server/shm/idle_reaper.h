// The idle reaper both region registries (shared memory, shm/region_registry.h; GPU,
// gpu/gpu_region_registry.h) run on a thread of their own: every quarter of the idle limit
// (between 50 ms and 1 s) it unregisters the regions unused for that long, and lets go of
// them outside the registry's lock (unmapping or releasing may be slow).
#pragma once

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <vector>

namespace skinserve::server {

// `regions`: a map of name to shared_ptr (null: a name reserved while it is being set up),
// guarded by `mutex`; `erase(it)` unregisters one under the lock; `now_ns()` the clock the
// regions' last_used_ns() reads; returns once `stopping` is set (and `wake` notified).
template <typename Regions, typename Erase, typename Now>
void ReapIdleRegions(std::mutex& mutex, std::condition_variable& wake, const bool& stopping,
                     Regions& regions, double idle_seconds, const char* kind, Erase erase,
                     Now now_ns) {
  const auto idle = std::chrono::duration<double>(idle_seconds);
  const auto period = std::chrono::duration_cast<std::chrono::milliseconds>(
      std::clamp(idle / 4, std::chrono::duration<double>(0.05), std::chrono::duration<double>(1)));
  std::vector<typename Regions::mapped_type> dropped;  // let go of outside the lock
  std::unique_lock lock(mutex);
  while (!stopping) {
    wake.wait_for(lock, period);
    const int64_t now = now_ns();
    for (auto it = regions.begin(); it != regions.end();) {
      auto next = std::next(it);
      const auto& region = it->second;
      if (region != nullptr &&
          static_cast<double>(now - region->last_used_ns()) * 1e-9 >= idle_seconds) {
        spdlog::info("{} '{}' of {} unregistered: unused for --shm-idle-seconds = {}", kind,
                     region->name(), region->owner(), idle_seconds);
        dropped.push_back(region);
        erase(it);
      }
      it = next;
    }
    lock.unlock();
    dropped.clear();
    lock.lock();
  }
}

}  // namespace skinserve::server
