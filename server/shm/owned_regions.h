// OwnedRegions: what both region registries (shared memory, shm/region_registry.h; GPU,
// gpu/gpu_region_registry.h) keep the same way. A region is kept under (owner id, name) and
// exists for its owner alone: found, listed and dropped only by the owner's id. A name is
// reserved (a null entry) while its region is set up outside the registry's lock, after the
// name and the limits were checked: regions in all, regions of one owner, bytes held. Not
// locked itself: the registry's mutex guards every call.
#pragma once

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "shm/region_owner.h"
#include "skinserve/model/status.h"

namespace skinserve::server {

// The steady clock in nanoseconds, which regions' last use is kept in.
inline int64_t RegionClockNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// How a registry names its regions and its limits in what it answers.
struct RegionWords {
  const char* kind;         // "region", "GPU region"
  const char* max_regions;  // the option limiting regions in all
  const char* budget;       // the option limiting bytes, in MiB
  const char* held;         // what the bytes are: "mapped", "imported"
};

struct OwnedRegionLimits {
  uint64_t budget_bytes = 0;
  uint32_t max_regions = 0;
  uint32_t max_per_owner = 0;  // --shm-max-regions-per-connection
  double idle_seconds = 0;     // --shm-idle-seconds: named when a region is gone
};

template <typename Region>
class OwnedRegions {
 public:
  using Key = std::pair<std::string, std::string>;  // (owner id, name)
  using Map = std::map<Key, std::shared_ptr<Region>>;

  OwnedRegions(RegionWords words, OwnedRegionLimits limits) : words_(words), limits_(limits) {}

  // INVALID_ARGUMENT unless the name is 1-64 characters of [A-Za-z0-9._-].
  Status CheckName(const std::string& name) const {
    const bool valid = !name.empty() && name.size() <= kMaxNameLength &&
                       std::all_of(name.begin(), name.end(), [](char c) {
                         return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
                                (c >= '0' && c <= '9') || c == '.' || c == '_' || c == '-';
                       });
    if (valid) return Status::Ok();
    return InvalidArgument(fmt::format("{} name '{}' is not 1-{} characters of [A-Za-z0-9._-]",
                                       words_.kind, name, kMaxNameLength));
  }

  // Reserves `name` and `bytes` for `owner`: ALREADY_EXISTS for a name the owner uses,
  // RESOURCE_EXHAUSTED naming the limit it would pass (counted in rejected()).
  Status Reserve(const std::string& name, uint64_t bytes, const RegionOwner& owner) {
    if (regions_.count({owner.id, name}) > 0) {
      return AlreadyExists(
          fmt::format("this client has a {} named '{}' already; unregister it first or choose "
                      "another name",
                      words_.kind, name));
    }
    if (Status s = CheckLimits(name, bytes, owner); !s.ok()) {
      ++rejected_;
      return s;
    }
    bytes_ += bytes;
    ++per_owner_[owner.id];
    regions_.emplace(Key{owner.id, name}, nullptr);
    return Status::Ok();
  }

  // The reserved name's region, now set up.
  void Enter(const RegionOwner& owner, const std::string& name, std::shared_ptr<Region> region) {
    regions_[{owner.id, name}] = std::move(region);
  }

  // Drops a reservation or a region (by its iterator), with its bytes.
  void Release(typename Map::iterator it, uint64_t bytes) {
    const std::string owner = it->first.first;
    regions_.erase(it);
    bytes_ -= bytes;
    if (auto count = per_owner_.find(owner); count != per_owner_.end() && --count->second == 0) {
      per_owner_.erase(count);
    }
  }
  void Release(const RegionOwner& owner, const std::string& name, uint64_t bytes) {
    if (auto it = regions_.find({owner.id, name}); it != regions_.end()) Release(it, bytes);
  }

  // The owner's region of that name, for unregistering it: NOT_FOUND if there is none.
  Result<typename Map::iterator> FindToRemove(const std::string& name, const RegionOwner& owner) {
    auto it = regions_.find({owner.id, name});
    if (it == regions_.end() || it->second == nullptr) {
      return NotFound(fmt::format("this client has no {} named '{}'", words_.kind, name));
    }
    return it;
  }

  // The owner's region a frame names, its use counted at `now_ns`. FAILED_PRECONDITION
  // when there is none: not NOT_FOUND, which on a frame means "upload the mesh again" (the
  // wire contract).
  Result<std::shared_ptr<Region>> Acquire(const std::string& name, const RegionOwner& owner,
                                          int64_t now_ns) {
    auto it = regions_.find({owner.id, name});
    if (it == regions_.end() || it->second == nullptr) {
      return FailedPrecondition(fmt::format(
          "this client has no {} named '{}' (never registered, unregistered, or idle for "
          "--shm-idle-seconds = {}); register it again",
          words_.kind, name, limits_.idle_seconds));
    }
    it->second->Touch(now_ns);
    return it->second;
  }

  // `info_of(region)` for each of the owner's regions, in name order.
  template <typename InfoOf>
  auto List(const RegionOwner& owner, InfoOf info_of) const {
    std::vector<decltype(info_of(std::declval<const Region&>()))> out;
    for (auto it = regions_.lower_bound({owner.id, ""});
         it != regions_.end() && it->first.first == owner.id; ++it) {
      if (it->second != nullptr) out.push_back(info_of(*it->second));
    }
    return out;
  }

  Map& map() { return regions_; }
  const Map& map() const { return regions_; }
  uint64_t bytes() const { return bytes_; }
  uint64_t rejected() const { return rejected_; }

 private:
  static constexpr std::size_t kMaxNameLength = 64;

  Status CheckLimits(const std::string& name, uint64_t bytes, const RegionOwner& owner) const {
    if (regions_.size() >= limits_.max_regions) {
      return ResourceExhausted(fmt::format("{} '{}' refused: the server holds {} = {} {}s already",
                                           words_.kind, name, words_.max_regions,
                                           limits_.max_regions, words_.kind));
    }
    if (auto it = per_owner_.find(owner.id);
        it != per_owner_.end() && it->second >= limits_.max_per_owner) {
      return ResourceExhausted(fmt::format(
          "{} '{}' refused: this client holds --shm-max-regions-per-connection = {} {}s already",
          words_.kind, name, limits_.max_per_owner, words_.kind));
    }
    if (bytes > limits_.budget_bytes - std::min(bytes_, limits_.budget_bytes)) {
      return ResourceExhausted(fmt::format(
          "{} '{}' refused: {} more bytes would take the {} {} bytes beyond {} = {} MiB",
          words_.kind, name, bytes, bytes_, words_.held, words_.budget,
          limits_.budget_bytes >> 20));
    }
    return Status::Ok();
  }

  const RegionWords words_;
  const OwnedRegionLimits limits_;
  Map regions_;  // a null region: the name is reserved while its region is set up
  std::map<std::string, uint32_t, std::less<>> per_owner_;
  uint64_t bytes_ = 0;
  uint64_t rejected_ = 0;  // reservations refused for a limit
};

}  // namespace skinserve::server
