#include "shm/region_handle.h"

#include <chrono>

#include "shm/sigbus_guard.h"

namespace skinserve::server {
namespace {

int64_t NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

Result<std::shared_ptr<MappedRegion>> RegionHandle::Resolve(const std::string& name,
                                                            const RegionCaller& caller) {
  if (caller.regions == nullptr) {
    return FailedPrecondition(
        "output names a shared-memory region, but this server's shared memory is off (--shm-dir "
        "is empty)");
  }
  if (!caller.owner.ok()) return caller.owner.status();
  if (name == name_) {
    if (std::shared_ptr<MappedRegion> region = region_.lock();
        region != nullptr && !region->removed() && region->owner() == caller.owner->id) {
      if (Status s = region->CheckNotBroken(); !s.ok()) return s;
      region->Touch(NowNs());
      return region;
    }
  }
  region_.reset();
  name_.clear();
  ++lookups_;
  Result<std::shared_ptr<MappedRegion>> region = caller.regions->Acquire(name, *caller.owner);
  if (!region.ok()) return region.status();
  if (Status s = (*region)->CheckIntact(); !s.ok()) return s;
  SigbusGuard::Install();  // still the SIGBUS handler, whatever a library did since
  name_ = name;
  region_ = *region;
  return region;
}

}  // namespace skinserve::server
