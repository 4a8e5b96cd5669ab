#include "shm/region_registry.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "shm/idle_reaper.h"
#include "shm/owned_regions.h"
#include "shm/sigbus_guard.h"

namespace skinserve::server {
namespace {

// A POSIX shared-memory name ("/name") or a plain file name: one component inside the dir.
Result<std::string> FileOf(const std::string& key) {
  std::string file = !key.empty() && key[0] == '/' ? key.substr(1) : key;
  if (file.empty() || file.size() > 255 || file == "." || file == ".." ||
      file.find('/') != std::string::npos || file.find('\0') != std::string::npos) {
    return InvalidArgument(fmt::format(
        "key '{}' must name one file inside the server's --shm-dir (a POSIX shared-memory "
        "name such as '/skin-1', or 'skin-1'): no other '/', not '.' or '..'",
        key));
  }
  return file;
}

}  // namespace

Result<std::unique_ptr<RegionRegistry>> RegionRegistry::Create(const RegionLimits& limits) {
  const int fd = open(limits.dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) {
    return InvalidArgument(
        fmt::format("--shm-dir '{}' cannot be opened: {}", limits.dir, std::strerror(errno)));
  }
  if (limits.max_regions > SigbusGuard::kMaxRanges) {
    close(fd);
    return InvalidArgument(
        fmt::format("--shm-max-regions = {} is above the most the server guards, {}",
                    limits.max_regions, SigbusGuard::kMaxRanges));
  }
  SigbusGuard::Install();
  return std::unique_ptr<RegionRegistry>(new RegionRegistry(limits, fd));
}

RegionRegistry::RegionRegistry(const RegionLimits& limits, int dir_fd)
    : limits_(limits),
      dir_fd_(dir_fd),
      owned_({.kind = "region",
              .max_regions = "--shm-max-regions",
              .budget = "--shm-budget-mb",
              .held = "mapped"},
             {.budget_bytes = limits.budget_bytes,
              .max_regions = limits.max_regions,
              .max_per_owner = limits.max_per_connection,
              .idle_seconds = limits.idle_seconds}),
      reaper_(ReapPeriod(limits.idle_seconds), [this] { ReapIdle(); }) {}

RegionRegistry::~RegionRegistry() {
  reaper_.Stop();  // before the regions it reads go
  std::lock_guard lock(mutex_);
  for (auto it = owned_.map().begin(); it != owned_.map().end();) {
    auto next = std::next(it);
    if (it->second != nullptr) EraseLocked(it, nullptr);
    it = next;
  }
  close(dir_fd_);
}

Result<RegionInfo> RegionRegistry::Register(const std::string& name, const std::string& key,
                                            uint64_t byte_size, const RegionOwner& owner) {
  if (Status s = owned_.CheckName(name); !s.ok()) return s;
  Result<std::string> file = FileOf(key);
  if (!file.ok()) return file.status();
  if (byte_size == 0) {
    return InvalidArgument(fmt::format("region '{}': byte_size must be above 0", name));
  }
  {
    // Reserve the name and the bytes, then open and map without the lock (file system calls).
    std::lock_guard lock(mutex_);
    if (Status s = owned_.Reserve(name, byte_size, owner); !s.ok()) return s;
  }
  Result<std::shared_ptr<MappedRegion>> region = MapAndEnter(name, *file, byte_size, owner);
  if (!region.ok()) return region.status();
  spdlog::info("region '{}' registered by {}: {} bytes of {}/{}", name, owner.id, byte_size,
               limits_.dir, *file);
  return InfoOf(**region, RegionClockNs());
}

Result<std::shared_ptr<MappedRegion>> RegionRegistry::MapAndEnter(const std::string& name,
                                                                  const std::string& file,
                                                                  uint64_t byte_size,
                                                                  const RegionOwner& owner) {
  Result<std::shared_ptr<MappedRegion>> region =
      MappedRegion::Open(dir_fd_, name, file, byte_size, owner.id, owner.file_uid);
  std::unique_lock lock(mutex_);
  Status failed = region.status();
  if (failed.ok() && files_.count((*region)->file()) > 0) {
    failed = AlreadyExists(fmt::format(
        "region '{}': key '{}' names a file registered already (by this client or another): "
        "one registration per file",
        name, file));
  }
  if (failed.ok()) {
    files_.insert((*region)->file());
    (*region)->Touch(RegionClockNs());
    owned_.Enter(owner, name, *region);
    return region;
  }
  owned_.Release(owner, name, byte_size);
  lock.unlock();
  region = failed;  // a mapping made for nothing goes here, outside the lock
  if (!owner.remote || failed.code() == StatusCode::kResourceExhausted) return failed;
  // Over TCP the caller learns nothing about the files in --shm-dir: not whether one
  // exists, nor its size, type, owner or registration. The operator's log says which.
  spdlog::info("region '{}' of {} refused: {}", name, owner.id, failed.message());
  return InvalidArgument(fmt::format(
      "region '{}': key '{}' cannot be registered. Over TCP the key must name a regular file "
      "in the server's --shm-dir, owned by the server's uid, holding at least byte_size "
      "bytes and registered by no one; the server does not say which of these failed",
      name, file));
}

void RegionRegistry::EraseLocked(Regions::iterator it, std::function<void()> on_unmapped) {
  std::shared_ptr<MappedRegion> region = std::move(it->second);
  owned_.Release(it, region->byte_size());
  files_.erase(region->file());
  frames_of_removed_ += region->frames();
  region->MarkRemoved(std::move(on_unmapped));
  // Unmapped here unless a frame still holds it; then when that frame lets go.
}

Status RegionRegistry::Unregister(const std::string& name, const RegionOwner& owner,
                                  std::function<void()> on_unmapped) {
  std::shared_ptr<MappedRegion> last;
  {
    std::lock_guard lock(mutex_);
    auto it = owned_.FindToRemove(name, owner);
    if (!it.ok()) return it.status();
    last = (*it)->second;  // unmapped outside the lock if nothing else holds it
    EraseLocked(*it, std::move(on_unmapped));
  }
  spdlog::info("region '{}' of {} unregistered", name, owner.id);
  return Status::Ok();
}

Result<std::shared_ptr<MappedRegion>> RegionRegistry::Acquire(const std::string& name,
                                                              const RegionOwner& owner) {
  std::lock_guard lock(mutex_);
  return owned_.Acquire(name, owner, RegionClockNs());
}

RegionInfo RegionRegistry::InfoOf(const MappedRegion& region, int64_t now_ns) const {
  return {region.name(), region.key(), region.byte_size(), region.frames(),
          static_cast<double>(now_ns - region.last_used_ns()) * 1e-9};
}

std::vector<RegionInfo> RegionRegistry::List(const RegionOwner& owner) const {
  const int64_t now = RegionClockNs();
  std::lock_guard lock(mutex_);
  return owned_.List(owner, [&](const MappedRegion& region) { return InfoOf(region, now); });
}

RegionStats RegionRegistry::Stats() const {
  std::lock_guard lock(mutex_);
  RegionStats stats;
  stats.budget_bytes = limits_.budget_bytes;
  stats.mapped_bytes = owned_.bytes();
  stats.rejected = owned_.rejected();
  stats.frames = frames_of_removed_;
  for (const auto& [name, region] : owned_.map()) {
    if (region == nullptr) continue;
    ++stats.regions;
    stats.frames += region->frames();
  }
  return stats;
}

void RegionRegistry::ReapIdle() {
  // Declared before the lock, so destroyed after it: the regions are let go of unlocked.
  std::vector<std::shared_ptr<MappedRegion>> idle;
  std::lock_guard lock(mutex_);
  idle = TakeIdleRegions(owned_.map(), limits_.idle_seconds, RegionClockNs(), "region",
                         [&](Regions::iterator it) { EraseLocked(it, nullptr); });
}

}  // namespace skinserve::server
