// The idle reaper both region registries (shared memory, shm/region_registry.h; GPU,
// gpu/gpu_region_registry.h) run on a PeriodicThread: every quarter of the idle limit (between
// 50 ms and 1 s) it unregisters the regions unused for that long, and lets go of them outside
// the registry's lock (unmapping or releasing may be slow).
#pragma once

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <iterator>
#include <vector>

namespace skinserve::server {

inline std::chrono::nanoseconds ReapPeriod(double idle_seconds) {
  const double seconds = std::clamp(idle_seconds / 4, 0.05, 1.0);
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
      std::chrono::duration<double>(seconds));
}

// One round, under the registry's lock. `regions`: a map of name to shared_ptr (null: a name
// reserved while it is being set up); `erase(it)` unregisters one; `now_ns` on the clock the
// regions' last_used_ns() reads. Returns the regions erased, for the caller to let go of once
// it has released the lock.
template <typename Regions, typename Erase>
std::vector<typename Regions::mapped_type> TakeIdleRegions(Regions& regions, double idle_seconds,
                                                           int64_t now_ns, const char* kind,
                                                           Erase erase) {
  std::vector<typename Regions::mapped_type> idle;
  for (auto it = regions.begin(); it != regions.end();) {
    auto next = std::next(it);
    const auto& region = it->second;
    if (region != nullptr &&
        static_cast<double>(now_ns - region->last_used_ns()) * 1e-9 >= idle_seconds) {
      spdlog::info("{} '{}' of {} unregistered: unused for --shm-idle-seconds = {}", kind,
                   region->name(), region->owner(), idle_seconds);
      idle.push_back(region);
      erase(it);
    }
    it = next;
  }
  return idle;
}

}  // namespace skinserve::server
