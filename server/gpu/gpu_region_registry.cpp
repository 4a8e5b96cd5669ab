#include "gpu/gpu_region_registry.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "shm/idle_reaper.h"
#include "shm/owned_regions.h"

namespace skinserve::server {
GpuRegion::~GpuRegion() {
  memory_.reset();  // the import released before the unregister's answer
  std::function<void()> done;
  {
    std::lock_guard lock(on_released_mutex_);
    done = std::move(on_released_);
  }
  if (done) done();
}

void GpuRegion::MarkRemoved(std::function<void()> on_released) {
  {
    std::lock_guard lock(on_released_mutex_);
    on_released_ = std::move(on_released);
  }
  removed_.store(true, std::memory_order_release);
}

Status GpuRegion::StillThere(uint64_t frame) const {
  if (!removed()) return Status::Ok();
  return FailedPrecondition(fmt::format(
      "GPU region '{}' was unregistered while frame {} was in flight: its output is undefined",
      name_, frame));
}

Status GpuRegion::FrameWritten(uint64_t frame) {
  if (Status s = StillThere(frame); !s.ok()) return s;
  if (Status s = memory_->SignalFrameWritten(); !s.ok()) {
    return Status(s.code(), fmt::format("GPU region '{}': frame {} is in the buffer, but its "
                                        "semaphore was not signalled: {}",
                                        name_, frame, s.message()));
  }
  CountFrame();
  return Status::Ok();
}

GpuRegionRegistry::GpuRegionRegistry(const GpuRegionLimits& limits)
    : limits_(limits),
      owned_({.kind = "GPU region",
              .max_regions = "--gpu-max-regions",
              .budget = "--gpu-region-budget-mb",
              .held = "imported"},
             {.budget_bytes = limits.budget_bytes,
              .max_regions = limits.max_regions,
              .max_per_owner = limits.max_per_owner,
              .idle_seconds = limits.idle_seconds}),
      reaper_(ReapPeriod(limits.idle_seconds), [this] { ReapIdle(); }) {}

GpuRegionRegistry::~GpuRegionRegistry() {
  reaper_.Stop();  // before the regions it reads go
  std::lock_guard lock(mutex_);
  for (auto it = owned_.map().begin(); it != owned_.map().end();) {
    auto next = std::next(it);
    if (it->second != nullptr) EraseLocked(it, nullptr);
    it = next;
  }
}

Result<GpuRegionInfo> GpuRegionRegistry::Register(const std::string& name, uint64_t byte_size,
                                                  const RegionOwner& owner,
                                                  const Importer& import) {
  if (Status s = owned_.CheckName(name); !s.ok()) return s;
  if (byte_size == 0) {
    return InvalidArgument(fmt::format("GPU region '{}': byte_size must be above 0", name));
  }
  {
    std::lock_guard lock(mutex_);
    if (Status s = owned_.Reserve(name, byte_size, owner); !s.ok()) return s;
  }
  Result<std::shared_ptr<DeviceMemory>> memory = import();  // no lock: a driver call
  std::lock_guard lock(mutex_);
  if (!memory.ok()) {
    owned_.Release(owner, name, byte_size);
    return Status(memory.status().code(),
                  fmt::format("GPU region '{}': {}", name, memory.status().message()));
  }
  auto region = std::make_shared<GpuRegion>(name, owner.id, std::move(memory).value());
  region->Touch(RegionClockNs());
  owned_.Enter(owner, name, region);
  spdlog::info("GPU region '{}' registered by {}: {} bytes, backend '{}'", name, owner.id,
               byte_size, region->memory().backend());
  return InfoOf(*region, RegionClockNs());
}

void GpuRegionRegistry::EraseLocked(Regions::iterator it, std::function<void()> on_released) {
  std::shared_ptr<GpuRegion> region = std::move(it->second);
  owned_.Release(it, region->byte_size());
  region->MarkRemoved(std::move(on_released));
  // Released here unless a frame still holds it; then when that frame lets go.
}

Status GpuRegionRegistry::Unregister(const std::string& name, const RegionOwner& owner,
                                     std::function<void()> on_released) {
  std::shared_ptr<GpuRegion> last;  // released outside the lock if nothing else holds it
  {
    std::lock_guard lock(mutex_);
    auto it = owned_.FindToRemove(name, owner);
    if (!it.ok()) return it.status();
    last = (*it)->second;
    EraseLocked(*it, std::move(on_released));
  }
  spdlog::info("GPU region '{}' of {} unregistered", name, owner.id);
  return Status::Ok();
}

Result<std::shared_ptr<GpuRegion>> GpuRegionRegistry::Acquire(const std::string& name,
                                                              const RegionOwner& owner) {
  std::lock_guard lock(mutex_);
  return owned_.Acquire(name, owner, RegionClockNs());
}

GpuRegionInfo GpuRegionRegistry::InfoOf(const GpuRegion& region, int64_t now_ns) const {
  return {region.name(),
          region.memory().backend(),
          region.byte_size(),
          region.frames(),
          static_cast<double>(now_ns - region.last_used_ns()) * 1e-9,
          region.memory().signals_semaphore()};
}

std::vector<GpuRegionInfo> GpuRegionRegistry::List(const RegionOwner& owner) const {
  const int64_t now = RegionClockNs();
  std::lock_guard lock(mutex_);
  return owned_.List(owner, [&](const GpuRegion& region) { return InfoOf(region, now); });
}

uint64_t GpuRegionRegistry::imported_bytes() const {
  std::lock_guard lock(mutex_);
  return owned_.bytes();
}

void GpuRegionRegistry::ReapIdle() {
  // Declared before the lock, so destroyed after it: the regions are let go of unlocked.
  std::vector<std::shared_ptr<GpuRegion>> idle;
  std::lock_guard lock(mutex_);
  idle = TakeIdleRegions(owned_.map(), limits_.idle_seconds, RegionClockNs(), "GPU region",
                         [&](Regions::iterator it) { EraseLocked(it, nullptr); });
}

}  // namespace skinserve::server
