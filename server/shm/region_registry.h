// RegionRegistry: the shared-memory regions clients registered (the same-host data plane,
// docs/serving/shared-memory.md). A region belongs to its owner (RegionOwner, the peer
// that registered it), is kept under the owner and its name, and only its owner may name
// it in a frame, list it or unregister it: to anyone else it does not exist. Every region
// is a file inside the operator's --shm-dir that its owner's uid owns, registered once
// (by anyone); together they map at most the budget, at most max_regions of them, and at
// most max_per_connection per owner. A region that no frame names for idle_seconds is
// unregistered (a client that went away leaves nothing mapped after that). The owners' side
// of it (names, limits, finding a region for its owner alone) is OwnedRegions
// (owned_regions.h), which the GPU regions share.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "shm/mapped_region.h"
#include "shm/owned_regions.h"
#include "shm/region_owner.h"
#include "threads/periodic_thread.h"

namespace skinserve::server {

class GpuRegionRegistry;

struct RegionLimits {
  std::string dir = "/dev/shm";
  uint64_t budget_bytes = 0;
  uint32_t max_regions = 256;
  uint32_t max_per_connection = 16;  // per owner (--shm-max-regions-per-connection)
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

  // Maps the region for `owner`. INVALID_ARGUMENT for a bad name, key, size or file;
  // ALREADY_EXISTS for a name the owner uses, or a file registered already (by anyone);
  // PERMISSION_DENIED for a file another uid owns; FAILED_PRECONDITION for a file whose
  // open would block; RESOURCE_EXHAUSTED naming the limit. For a remote owner (TCP) every
  // error about the file is one INVALID_ARGUMENT that says nothing about it.
  Result<RegionInfo> Register(const std::string& name, const std::string& key, uint64_t byte_size,
                              const RegionOwner& owner);
  // Removes the owner's region (NOT_FOUND if it has none of that name); `on_unmapped` runs
  // once no frame holds it and it is unmapped, which may be at once, on this thread.
  Status Unregister(const std::string& name, const RegionOwner& owner,
                    std::function<void()> on_unmapped);
  // The owner's region a frame names, pinned while the frame holds the pointer. Counts as
  // use. FAILED_PRECONDITION when the owner has none by that name.
  Result<std::shared_ptr<MappedRegion>> Acquire(const std::string& name, const RegionOwner& owner);
  std::vector<RegionInfo> List(const RegionOwner& owner) const;
  RegionStats Stats() const;

 private:
  explicit RegionRegistry(const RegionLimits& limits, int dir_fd);
  void ReapIdle();  // the reaper thread
  using Regions = OwnedRegions<MappedRegion>::Map;
  void EraseLocked(Regions::iterator it, std::function<void()> on_unmapped);
  RegionInfo InfoOf(const MappedRegion& region, int64_t now_ns) const;
  // Maps the file (no lock held) and enters it, or why not.
  Result<std::shared_ptr<MappedRegion>> MapAndEnter(const std::string& name,
                                                    const std::string& file, uint64_t byte_size,
                                                    const RegionOwner& owner);

  const RegionLimits limits_;
  const int dir_fd_;
  mutable std::mutex mutex_;
  OwnedRegions<MappedRegion> owned_;         // a name reserved while its file is opened
  std::set<std::pair<dev_t, ino_t>> files_;  // the files registered: one registration each
  uint64_t frames_of_removed_ = 0;           // frames written into regions no longer registered
  PeriodicThread reaper_;                    // last: it reads every member above
};

// What a frame call may do with regions: the registry (null: shared memory is off) and
// the caller as an owner, or why it is none (PERMISSION_DENIED, see RegionOwnerOf).
struct RegionCaller {
  RegionRegistry* regions = nullptr;
  Result<RegionOwner> owner = PermissionDenied("this call may not use shared-memory regions");
  GpuRegionRegistry* gpu_regions = nullptr;  // null: GPU regions are off (gpu/)
};

}  // namespace skinserve::server
