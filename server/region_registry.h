// RegionRegistry: the shared-memory regions clients registered, by name (the same-host
// data plane, docs/serving/shared-memory.md). Every region is a file inside the operator's
// --shm-dir; together they map at most the budget, at most max_regions of them, and at
// most max_per_connection per client connection. A region that no frame names for
// idle_seconds is unregistered (a client that went away leaves nothing mapped after that).
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "mapped_region.h"

namespace skinserve::server {

struct RegionLimits {
  std::string dir = "/dev/shm";
  uint64_t budget_bytes = 0;
  uint32_t max_regions = 256;
  uint32_t max_per_connection = 16;
  double idle_seconds = 60;
};

struct RegionInfo {
  std::string name, key;
  uint64_t byte_size = 0;
  uint64_t frames_written = 0;
  double idle_seconds = 0;
};

struct RegionStats {
  uint64_t regions = 0;
  uint64_t mapped_bytes = 0;
  uint64_t budget_bytes = 0;
  uint64_t frames = 0;    // written into regions, over the server's life
  uint64_t rejected = 0;  // registrations refused for a limit
};

class RegionRegistry {
 public:
  // Opens --shm-dir (which must exist) and starts the idle reaper.
  static Result<std::unique_ptr<RegionRegistry>> Create(const RegionLimits& limits);
  ~RegionRegistry();  // stops the reaper; mappings go as frames let go of them

  const RegionLimits& limits() const { return limits_; }

  // Maps the region for `owner` (the client's connection, for the per-connection cap).
  // INVALID_ARGUMENT for a bad name, key or size; ALREADY_EXISTS for a name taken;
  // RESOURCE_EXHAUSTED naming the limit.
  Result<RegionInfo> Register(const std::string& name, const std::string& key, uint64_t byte_size,
                              const std::string& owner);
  // Removes the region (NOT_FOUND if none); `on_unmapped` runs once no frame holds it and
  // it is unmapped, which may be at once, on this thread.
  Status Unregister(const std::string& name, std::function<void()> on_unmapped);
  // The region a frame names, pinned while the frame holds the pointer. Counts as use.
  // FAILED_PRECONDITION when none is registered by that name.
  Result<std::shared_ptr<MappedRegion>> Acquire(const std::string& name);
  std::vector<RegionInfo> List() const;
  RegionStats Stats() const;

 private:
  explicit RegionRegistry(const RegionLimits& limits, int dir_fd);
  void ReapIdle();  // the reaper thread
  void EraseLocked(std::map<std::string, std::shared_ptr<MappedRegion>, std::less<>>::iterator it,
                   std::function<void()> on_unmapped);
  RegionInfo InfoOf(const MappedRegion& region, int64_t now_ns) const;

  const RegionLimits limits_;
  const int dir_fd_;
  mutable std::mutex mutex_;
  std::map<std::string, std::shared_ptr<MappedRegion>, std::less<>> regions_;
  std::map<std::string, uint32_t, std::less<>> per_owner_;
  uint64_t mapped_bytes_ = 0;
  uint64_t frames_of_removed_ = 0;  // frames written into regions no longer registered
  uint64_t rejected_ = 0;
  bool stopping_ = false;
  std::condition_variable wake_;
  std::thread reaper_;
};

}  // namespace skinserve::server
