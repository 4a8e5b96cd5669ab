// GpuRegionRegistry: the GPU regions clients registered (docs/serving/gpu-regions.md):
// buffers on the server's GPU that another API allocated and the engine's backend
// imported (DeviceMemory). The rules are the shared-memory regions' (region_registry.h;
// both keep their regions in shm/owned_regions.h):
// a region belongs to the RegionOwner that registered it and does not exist for anyone
// else; names are the owner's own; together they hold at most the budget, at most
// max_regions of them, max_per_owner per owner; unregistering answers once no frame holds
// the region and its import is released; a region no frame names for idle_seconds is
// unregistered (a client gone away leaves nothing imported).
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "shm/owned_regions.h"
#include "shm/region_owner.h"
#include "skinserve/engine/device_memory.h"
#include "skinserve/model/status.h"
#include "threads/periodic_thread.h"

namespace skinserve::server {

struct GpuRegionLimits {
  uint64_t budget_bytes = 8ull << 30;  // --gpu-region-budget-mb
  uint32_t max_regions = 64;           // --gpu-max-regions
  uint32_t max_per_owner = 16;         // --shm-max-regions-per-connection
  double idle_seconds = 60;            // --shm-idle-seconds
};

// One registered region. Frames hold it by shared_ptr while they write; when the last
// holder lets go the import is released, then on_released (an unregister's answer) runs.
class GpuRegion {
 public:
  GpuRegion(std::string name, std::string owner, std::shared_ptr<DeviceMemory> memory)
      : name_(std::move(name)), owner_(std::move(owner)), memory_(std::move(memory)) {}
  ~GpuRegion();
  const std::string& name() const { return name_; }
  const std::string& owner() const { return owner_; }
  const DeviceMemory& memory() const { return *memory_; }
  uint64_t byte_size() const { return memory_->byte_size(); }
  bool removed() const { return removed_.load(std::memory_order_acquire); }
  void MarkRemoved(std::function<void()> on_released);
  void Touch(int64_t now_ns) { last_used_ns_.store(now_ns, std::memory_order_relaxed); }
  int64_t last_used_ns() const { return last_used_ns_.load(std::memory_order_relaxed); }
  void CountFrame() { frames_.fetch_add(1, std::memory_order_relaxed); }
  // A frame is in the region: FAILED_PRECONDITION if the region was unregistered
  // meanwhile (its output is undefined, nothing signalled); else its semaphore, if it was
  // registered with one, signalled once, and the frame counted.
  Status FrameWritten(uint64_t frame);
  // FrameWritten's first check alone (a tick's character: the tick signals once).
  Status StillThere(uint64_t frame) const;
  uint64_t frames() const { return frames_.load(std::memory_order_relaxed); }

 private:
  const std::string name_, owner_;
  std::shared_ptr<DeviceMemory> memory_;
  std::atomic<bool> removed_{false};
  std::atomic<int64_t> last_used_ns_{0};
  std::atomic<uint64_t> frames_{0};
  std::mutex on_released_mutex_;
  std::function<void()> on_released_;
};

struct GpuRegionInfo {
  std::string name, backend;
  uint64_t byte_size = 0;
  uint64_t frames_written = 0;
  double idle_seconds = 0;
  bool signals_semaphore = false;
};

class GpuRegionRegistry {
 public:
  using Importer = std::function<Result<std::shared_ptr<DeviceMemory>>()>;
  explicit GpuRegionRegistry(const GpuRegionLimits& limits);
  ~GpuRegionRegistry();  // stops the reaper; imports go as frames let go of them
  const GpuRegionLimits& limits() const { return limits_; }

  // Checks the name and the limits, reserves them, runs `import` without the lock and
  // enters its memory for `owner` (`byte_size` is what the client declared: the memory
  // must be that size). INVALID_ARGUMENT for a bad name or size; ALREADY_EXISTS for a name
  // the owner uses; RESOURCE_EXHAUSTED naming the limit (`import` not run); else the
  // import's error.
  Result<GpuRegionInfo> Register(const std::string& name, uint64_t byte_size,
                                 const RegionOwner& owner, const Importer& import);
  // As RegionRegistry::Unregister: NOT_FOUND if the owner has no region of that name.
  Status Unregister(const std::string& name, const RegionOwner& owner,
                    std::function<void()> on_released);
  // The owner's region a frame names, pinned while held; FAILED_PRECONDITION if none.
  Result<std::shared_ptr<GpuRegion>> Acquire(const std::string& name, const RegionOwner& owner);
  std::vector<GpuRegionInfo> List(const RegionOwner& owner) const;
  uint64_t imported_bytes() const;

 private:
  using Regions = OwnedRegions<GpuRegion>::Map;
  void EraseLocked(Regions::iterator it, std::function<void()> on_released);
  GpuRegionInfo InfoOf(const GpuRegion& region, int64_t now_ns) const;
  void ReapIdle();

  const GpuRegionLimits limits_;
  mutable std::mutex mutex_;
  OwnedRegions<GpuRegion> owned_;  // a name reserved while its import runs
  PeriodicThread reaper_;          // last: it reads every member above
};

}  // namespace skinserve::server
