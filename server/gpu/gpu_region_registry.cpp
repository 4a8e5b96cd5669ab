#include "gpu/gpu_region_registry.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>

#include "shm/idle_reaper.h"

namespace skinserve::server {
namespace {

constexpr std::size_t kMaxNameLength = 64;

int64_t NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

Status CheckName(const std::string& name) {
  const bool valid = !name.empty() && name.size() <= kMaxNameLength &&
                     std::all_of(name.begin(), name.end(), [](char c) {
                       return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
                              (c >= '0' && c <= '9') || c == '.' || c == '_' || c == '-';
                     });
  if (valid) return Status::Ok();
  return InvalidArgument(fmt::format(
      "GPU region name '{}' is not 1-{} characters of [A-Za-z0-9._-]", name, kMaxNameLength));
}

}  // namespace

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

GpuRegionRegistry::GpuRegionRegistry(const GpuRegionLimits& limits) : limits_(limits) {
  reaper_ = std::thread([this] { ReapIdle(); });
}

GpuRegionRegistry::~GpuRegionRegistry() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  reaper_.join();
  std::lock_guard lock(mutex_);
  for (auto it = regions_.begin(); it != regions_.end();) {
    auto next = std::next(it);
    if (it->second != nullptr) EraseLocked(it, nullptr);
    it = next;
  }
}

Status GpuRegionRegistry::ReserveLocked(const std::string& name, uint64_t byte_size,
                                        const RegionOwner& owner) {
  if (regions_.count({owner.id, name}) > 0) {
    return AlreadyExists(fmt::format(
        "this client has a GPU region named '{}' already; unregister it first or choose another "
        "name",
        name));
  }
  if (regions_.size() >= limits_.max_regions) {
    return ResourceExhausted(fmt::format(
        "GPU region '{}' refused: the server holds --gpu-max-regions = {} GPU regions already",
        name, limits_.max_regions));
  }
  if (auto it = per_owner_.find(owner.id);
      it != per_owner_.end() && it->second >= limits_.max_per_owner) {
    return ResourceExhausted(fmt::format(
        "GPU region '{}' refused: this client holds --shm-max-regions-per-connection = {} GPU "
        "regions already",
        name, limits_.max_per_owner));
  }
  if (byte_size > limits_.budget_bytes - std::min(imported_bytes_, limits_.budget_bytes)) {
    return ResourceExhausted(
        fmt::format("GPU region '{}' refused: {} more bytes would take the {} imported bytes "
                    "beyond --gpu-region-budget-mb = {} MiB",
                    name, byte_size, imported_bytes_, limits_.budget_bytes >> 20));
  }
  imported_bytes_ += byte_size;
  ++per_owner_[owner.id];
  regions_.emplace(Key{owner.id, name}, nullptr);
  return Status::Ok();
}

void GpuRegionRegistry::ReleaseReservationLocked(const Key& key, uint64_t byte_size) {
  regions_.erase(key);
  imported_bytes_ -= byte_size;
  if (--per_owner_[key.first] == 0) per_owner_.erase(key.first);
}

Result<GpuRegionInfo> GpuRegionRegistry::Register(const std::string& name, uint64_t byte_size,
                                                  const RegionOwner& owner,
                                                  const Importer& import) {
  if (Status s = CheckName(name); !s.ok()) return s;
  if (byte_size == 0) {
    return InvalidArgument(fmt::format("GPU region '{}': byte_size must be above 0", name));
  }
  {
    std::lock_guard lock(mutex_);
    if (Status s = ReserveLocked(name, byte_size, owner); !s.ok()) return s;
  }
  Result<std::shared_ptr<DeviceMemory>> memory = import();  // no lock: a driver call
  std::lock_guard lock(mutex_);
  const Key key{owner.id, name};
  if (!memory.ok()) {
    ReleaseReservationLocked(key, byte_size);
    return Status(memory.status().code(),
                  fmt::format("GPU region '{}': {}", name, memory.status().message()));
  }
  auto region = std::make_shared<GpuRegion>(name, owner.id, std::move(memory).value());
  region->Touch(NowNs());
  regions_[key] = region;
  spdlog::info("GPU region '{}' registered by {}: {} bytes, backend '{}'", name, owner.id,
               byte_size, region->memory().backend());
  return InfoOf(*region, NowNs());
}

void GpuRegionRegistry::EraseLocked(Regions::iterator it, std::function<void()> on_released) {
  std::shared_ptr<GpuRegion> region = std::move(it->second);
  ReleaseReservationLocked(it->first, region->byte_size());
  region->MarkRemoved(std::move(on_released));
  // Released here unless a frame still holds it; then when that frame lets go.
}

Status GpuRegionRegistry::Unregister(const std::string& name, const RegionOwner& owner,
                                     std::function<void()> on_released) {
  std::shared_ptr<GpuRegion> last;  // released outside the lock if nothing else holds it
  {
    std::lock_guard lock(mutex_);
    auto it = regions_.find({owner.id, name});
    if (it == regions_.end() || it->second == nullptr) {
      return NotFound(fmt::format("this client has no GPU region named '{}'", name));
    }
    last = it->second;
    EraseLocked(it, std::move(on_released));
  }
  spdlog::info("GPU region '{}' of {} unregistered", name, owner.id);
  return Status::Ok();
}

Result<std::shared_ptr<GpuRegion>> GpuRegionRegistry::Acquire(const std::string& name,
                                                              const RegionOwner& owner) {
  std::lock_guard lock(mutex_);
  auto it = regions_.find({owner.id, name});
  if (it == regions_.end() || it->second == nullptr) {
    return FailedPrecondition(fmt::format(
        "this client has no GPU region named '{}' (never registered, unregistered, or idle for "
        "--shm-idle-seconds = {}); register it again",
        name, limits_.idle_seconds));
  }
  it->second->Touch(NowNs());
  return it->second;
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
  const int64_t now = NowNs();
  std::lock_guard lock(mutex_);
  std::vector<GpuRegionInfo> out;
  for (auto it = regions_.lower_bound({owner.id, ""});
       it != regions_.end() && it->first.first == owner.id; ++it) {
    if (it->second != nullptr) out.push_back(InfoOf(*it->second, now));
  }
  return out;
}

uint64_t GpuRegionRegistry::imported_bytes() const {
  std::lock_guard lock(mutex_);
  return imported_bytes_;
}

void GpuRegionRegistry::ReapIdle() {
  ReapIdleRegions(
      mutex_, wake_, stopping_, regions_, limits_.idle_seconds, "GPU region",
      [&](Regions::iterator it) { EraseLocked(it, nullptr); }, NowNs);
}

}  // namespace skinserve::server
