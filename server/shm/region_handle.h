// RegionHandle: a stream's hold on the shared-memory region its frames write into. The
// first frame that names a region resolves it (looked up by owner and name under the
// registry's lock, its file checked with fstat, the SIGBUS guard put back in place); the
// frames after it that name the same region only check, with two atomic loads, that it
// was neither unregistered nor broken by a truncation (the guard marks that), and touch
// it for the idle clock. The handle holds the region weakly between frames, so an
// unregister never waits for an idle stream; each frame pins it while it writes.
#pragma once

#include <memory>
#include <string>

#include "shm/mapped_region.h"
#include "shm/region_registry.h"
#include "skinserve/model/status.h"

namespace skinserve::server {

class RegionHandle {
 public:
  // The region named `name` for `caller`'s frame, pinned: the one resolved before if it
  // still stands, else resolved anew. Errors as RegionRegistry::Acquire and
  // MappedRegion::CheckIntact.
  Result<std::shared_ptr<MappedRegion>> Resolve(const std::string& name,
                                                const RegionCaller& caller);
  // Resolutions that looked the region up (the first, and after a change): for tests.
  uint64_t lookups() const { return lookups_; }

 private:
  std::string name_;
  std::weak_ptr<MappedRegion> region_;
  uint64_t lookups_ = 0;
};

}  // namespace skinserve::server
