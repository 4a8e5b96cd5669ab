#include "shm/region_registry.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "shm/idle_reaper.h"
#include "shm/sigbus_guard.h"

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
  return InvalidArgument(fmt::format("region name '{}' is not 1-{} characters of [A-Za-z0-9._-]",
                                     name, kMaxNameLength));
}

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
    : limits_(limits), dir_fd_(dir_fd) {
  reaper_ = std::thread([this] { ReapIdle(); });
}

RegionRegistry::~RegionRegistry() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  reaper_.join();
  std::lock_guard lock(mutex_);
  while (!regions_.empty()) EraseLocked(regions_.begin(), nullptr);
  close(dir_fd_);
}

Result<RegionInfo> RegionRegistry::Register(const std::string& name, const std::string& key,
                                            uint64_t byte_size, const RegionOwner& owner) {
  if (Status s = CheckName(name); !s.ok()) return s;
  Result<std::string> file = FileOf(key);
  if (!file.ok()) return file.status();
  if (byte_size == 0) {
    return InvalidArgument(fmt::format("region '{}': byte_size must be above 0", name));
  }
  std::unique_lock lock(mutex_);
  const auto refuse = [&](std::string why) {
    ++rejected_;
    return ResourceExhausted(fmt::format("region '{}' refused: {}", name, why));
  };
  if (regions_.find({owner.id, name}) != regions_.end()) {
    return AlreadyExists(fmt::format(
        "this client has a region named '{}' already; unregister it first or choose another name",
        name));
  }
  if (regions_.size() >= limits_.max_regions) {
    return refuse(fmt::format("the server holds --shm-max-regions = {} regions already",
                              limits_.max_regions));
  }
  if (auto it = per_owner_.find(owner.id);
      it != per_owner_.end() && it->second >= limits_.max_per_connection) {
    return refuse(fmt::format("this client holds --shm-max-regions-per-connection = {} already",
                              limits_.max_per_connection));
  }
  if (byte_size > limits_.budget_bytes - std::min(mapped_bytes_, limits_.budget_bytes)) {
    return refuse(
        fmt::format("{} more bytes would take the regions' {} mapped bytes beyond "
                    "--shm-budget-mb = {} MiB",
                    byte_size, mapped_bytes_, limits_.budget_bytes >> 20));
  }
  // Reserve the name and the bytes, then open and map without the lock (file system calls).
  mapped_bytes_ += byte_size;
  ++per_owner_[owner.id];
  regions_.emplace(Key{owner.id, name}, nullptr);
  lock.unlock();
  Result<std::shared_ptr<MappedRegion>> region = MapAndEnter(name, *file, byte_size, owner);
  if (!region.ok()) return region.status();
  spdlog::info("region '{}' registered by {}: {} bytes of {}/{}", name, owner.id, byte_size,
               limits_.dir, *file);
  return InfoOf(**region, NowNs());
}

Result<std::shared_ptr<MappedRegion>> RegionRegistry::MapAndEnter(const std::string& name,
                                                                  const std::string& file,
                                                                  uint64_t byte_size,
                                                                  const RegionOwner& owner) {
  Result<std::shared_ptr<MappedRegion>> region =
      MappedRegion::Open(dir_fd_, name, file, byte_size, owner.id, owner.file_uid);
  std::unique_lock lock(mutex_);
  auto it = regions_.find({owner.id, name});
  Status failed = region.status();
  if (failed.ok() && files_.count((*region)->file()) > 0) {
    failed = AlreadyExists(fmt::format(
        "region '{}': key '{}' names a file registered already (by this client or another): "
        "one registration per file",
        name, file));
  }
  if (failed.ok()) {
    files_.insert((*region)->file());
    (*region)->Touch(NowNs());
    it->second = *region;
    return region;
  }
  regions_.erase(it);
  mapped_bytes_ -= byte_size;
  if (--per_owner_[owner.id] == 0) per_owner_.erase(owner.id);
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
  regions_.erase(it);
  files_.erase(region->file());
  mapped_bytes_ -= region->byte_size();
  frames_of_removed_ += region->frames();
  if (auto owner = per_owner_.find(region->owner());
      owner != per_owner_.end() && --owner->second == 0) {
    per_owner_.erase(owner);
  }
  region->MarkRemoved(std::move(on_unmapped));
  // Unmapped here unless a frame still holds it; then when that frame lets go.
}

Status RegionRegistry::Unregister(const std::string& name, const RegionOwner& owner,
                                  std::function<void()> on_unmapped) {
  std::shared_ptr<MappedRegion> last;
  {
    std::lock_guard lock(mutex_);
    auto it = regions_.find({owner.id, name});
    if (it == regions_.end() || it->second == nullptr) {
      return NotFound(fmt::format("this client has no region named '{}'", name));
    }
    last = it->second;  // unmapped outside the lock if nothing else holds it
    EraseLocked(it, std::move(on_unmapped));
  }
  spdlog::info("region '{}' of {} unregistered", name, owner.id);
  return Status::Ok();
}

Result<std::shared_ptr<MappedRegion>> RegionRegistry::Acquire(const std::string& name,
                                                              const RegionOwner& owner) {
  std::lock_guard lock(mutex_);
  auto it = regions_.find({owner.id, name});
  if (it == regions_.end() || it->second == nullptr) {
    // Not NOT_FOUND: on a frame that means "upload the mesh again" (the wire contract).
    return FailedPrecondition(fmt::format(
        "this client has no region named '{}' (never registered, unregistered, or idle for "
        "--shm-idle-seconds = {}); register it again",
        name, limits_.idle_seconds));
  }
  it->second->Touch(NowNs());
  return it->second;
}

RegionInfo RegionRegistry::InfoOf(const MappedRegion& region, int64_t now_ns) const {
  return {region.name(), region.key(), region.byte_size(), region.frames(),
          static_cast<double>(now_ns - region.last_used_ns()) * 1e-9};
}

std::vector<RegionInfo> RegionRegistry::List(const RegionOwner& owner) const {
  const int64_t now = NowNs();
  std::lock_guard lock(mutex_);
  std::vector<RegionInfo> out;
  for (auto it = regions_.lower_bound({owner.id, ""});
       it != regions_.end() && it->first.first == owner.id; ++it) {
    if (it->second != nullptr) out.push_back(InfoOf(*it->second, now));
  }
  return out;
}

RegionStats RegionRegistry::Stats() const {
  std::lock_guard lock(mutex_);
  RegionStats stats;
  stats.budget_bytes = limits_.budget_bytes;
  stats.mapped_bytes = mapped_bytes_;
  stats.rejected = rejected_;
  stats.frames = frames_of_removed_;
  for (const auto& [name, region] : regions_) {
    if (region == nullptr) continue;
    ++stats.regions;
    stats.frames += region->frames();
  }
  return stats;
}

void RegionRegistry::ReapIdle() {
  ReapIdleRegions(
      mutex_, wake_, stopping_, regions_, limits_.idle_seconds, "region",
      [&](Regions::iterator it) { EraseLocked(it, nullptr); }, NowNs);
}

}  // namespace skinserve::server
