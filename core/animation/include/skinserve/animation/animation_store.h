// AnimationStore: the skeletons and compact clips a server holds, content-addressed (the
// same content uploaded twice is stored once, under one id) and charged to one byte budget.
// A skeleton or clip is stored whole or not at all: everything is checked and built before
// anything is charged or inserted. Lookups hand out shared pointers, so a pose being
// computed keeps what it reads alive while another call deletes it. Thread-safe.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <shared_mutex>
#include <string>

#include "skinserve/animation/compact_clip.h"
#include "skinserve/animation/raw_clip.h"
#include "skinserve/animation/skeleton.h"
#include "skinserve/model/status.h"

namespace skinserve::animation {

struct SkeletonInfo {
  std::string id;  // SHA-256 of SkeletonBytes(), lowercase hex
  uint32_t joint_count = 0;
  uint32_t palette_size = 0;
  uint64_t bytes = 0;  // charged to the budget
  bool already_stored = false;
};

struct ClipInfo {
  std::string id;  // CompactClip::id
  std::string name;
  float duration = 0;
  uint32_t joint_count = 0;
  uint32_t weight_count = 0;
  uint32_t tracks = 0;
  uint64_t bytes = 0;      // the compact clip's bytes: what the budget is charged
  uint64_t raw_bytes = 0;  // the float bytes it was built from (times and values)
  float max_error_mm = 0;  // the model-space bound it was built to (compact_clip.h)
  bool already_stored = false;
};

// A skeleton's canonical little-endian bytes: what its id hashes and what it costs.
std::vector<uint8_t> SkeletonBytes(const Skeleton& skeleton);

class AnimationStore {
 public:
  explicit AnimationStore(uint64_t budget_bytes) : budget_bytes_(budget_bytes) {}

  // Validates (INVALID_ARGUMENT naming the field) and stores; RESOURCE_EXHAUSTED naming
  // the budget when it cannot hold the skeleton.
  Result<SkeletonInfo> AddSkeleton(Skeleton skeleton);
  // Builds the compact clip for skeleton `skeleton_id` (NOT_FOUND: upload it first;
  // INVALID_ARGUMENT naming the track and field) and stores it; RESOURCE_EXHAUSTED naming
  // the budget when it cannot hold the clip. `options`: the error it is built to.
  Result<ClipInfo> AddClip(const RawClip& raw, const std::string& skeleton_id,
                           const ClipBuildOptions& options = {});

  std::shared_ptr<const Skeleton> FindSkeleton(const std::string& id) const;
  std::shared_ptr<const CompactClip> FindClip(const std::string& id) const;
  bool DeleteSkeleton(const std::string& id);
  bool DeleteClip(const std::string& id);

  uint64_t budget_bytes() const { return budget_bytes_; }
  uint64_t bytes() const;
  std::size_t skeleton_count() const;
  std::size_t clip_count() const;

 private:
  // RESOURCE_EXHAUSTED unless `bytes` more fit the budget; under mutex_.
  Status CheckBudgetLocked(const std::string& what, uint64_t bytes) const;

  const uint64_t budget_bytes_;
  mutable std::shared_mutex mutex_;
  uint64_t bytes_ = 0;
  struct StoredSkeleton {
    std::shared_ptr<const Skeleton> skeleton;
    uint64_t bytes = 0;
  };
  struct StoredClip {
    std::shared_ptr<const CompactClip> clip;
    uint64_t bytes = 0;
    uint64_t raw_bytes = 0;
  };
  std::map<std::string, StoredSkeleton, std::less<>> skeletons_;
  std::map<std::string, StoredClip, std::less<>> clips_;
};

}  // namespace skinserve::animation
