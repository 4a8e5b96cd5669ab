#include "skinserve/animation/animation_store.h"

#include <fmt/format.h>

#include <mutex>

#include "clip_id.h"

namespace skinserve::animation {
namespace {

template <typename T>
void Put(std::vector<uint8_t>& out, const T& v) {  // little-endian hosts, as CompactClip's
  const auto* p = reinterpret_cast<const uint8_t*>(&v);
  out.insert(out.end(), p, p + sizeof(T));
}

template <typename T>
void PutArray(std::vector<uint8_t>& out, const std::vector<T>& v) {
  Put(out, static_cast<uint32_t>(v.size()));
  const auto* p = reinterpret_cast<const uint8_t*>(v.data());
  out.insert(out.end(), p, p + v.size() * sizeof(T));
}

uint64_t RawBytes(const RawClip& raw) {
  uint64_t bytes = 0;
  for (const RawTrack& t : raw.tracks) bytes += 4 * (t.times.size() + t.values.size());
  return bytes;
}

double MiB(uint64_t bytes) { return static_cast<double>(bytes) / (1 << 20); }

}  // namespace

std::vector<uint8_t> SkeletonBytes(const Skeleton& s) {
  std::vector<uint8_t> out;
  constexpr char kMagic[8] = {'S', 'S', 'S', 'K', 'E', 'L', '1', '\0'};
  for (char c : kMagic) Put(out, c);
  PutArray(out, s.parents);
  PutArray(out, s.rest);  // Transform: 10 floats, no padding
  Put(out, static_cast<uint32_t>(s.names.size()));
  for (const std::string& name : s.names)
    PutArray(out, std::vector<char>(name.begin(), name.end()));
  PutArray(out, s.palette_joints);
  PutArray(out, s.inverse_bind);
  return out;
}

Status AnimationStore::CheckBudgetLocked(const std::string& what, uint64_t bytes) const {
  if (bytes_ + bytes <= budget_bytes_) return Status::Ok();
  return ResourceExhausted(
      fmt::format("{} needs {} bytes; the animation store holds {} of its {} bytes ({:.1f} MiB, "
                  "--clip-budget-mb): delete clips or raise the budget",
                  what, bytes, bytes_, budget_bytes_, MiB(budget_bytes_)));
}

Result<SkeletonInfo> AnimationStore::AddSkeleton(Skeleton skeleton) {
  if (Status s = ValidateSkeleton(skeleton); !s.ok()) return s;
  const std::vector<uint8_t> bytes = SkeletonBytes(skeleton);
  SkeletonInfo info{.id = ClipId(bytes),
                    .joint_count = skeleton.joint_count(),
                    .palette_size = skeleton.palette_size(),
                    .bytes = bytes.size()};
  std::unique_lock lock(mutex_);
  if (skeletons_.contains(info.id)) {
    info.already_stored = true;
    return info;
  }
  if (Status s = CheckBudgetLocked("the skeleton", info.bytes); !s.ok()) return s;
  skeletons_.emplace(
      info.id, StoredSkeleton{std::make_shared<const Skeleton>(std::move(skeleton)), info.bytes});
  bytes_ += info.bytes;
  return info;
}

Result<ClipInfo> AnimationStore::AddClip(const RawClip& raw, const std::string& skeleton_id,
                                         const ClipBuildOptions& options) {
  const std::shared_ptr<const Skeleton> skeleton = FindSkeleton(skeleton_id);
  if (skeleton == nullptr) {
    return NotFound(
        fmt::format("skeleton_id '{}' is not stored: upload the skeleton first", skeleton_id));
  }
  Result<CompactClip> clip = BuildCompactClip(raw, *skeleton, options);  // outside the lock
  if (!clip.ok()) return clip.status();
  ClipInfo info{.id = clip->id,
                .name = clip->name,
                .duration = clip->duration,
                .joint_count = clip->joint_count,
                .weight_count = clip->weight_count,
                .tracks = static_cast<uint32_t>(clip->tracks.size()),
                .bytes = clip->Serialize().size(),
                .raw_bytes = RawBytes(raw),
                .max_error_mm = clip->max_error_mm};
  std::unique_lock lock(mutex_);
  if (clips_.contains(info.id)) {
    info.already_stored = true;
    return info;
  }
  if (Status s = CheckBudgetLocked(fmt::format("clip '{}'", info.name), info.bytes); !s.ok()) {
    return s;
  }
  clips_.emplace(info.id, StoredClip{std::make_shared<const CompactClip>(std::move(*clip)),
                                     info.bytes, info.raw_bytes});
  bytes_ += info.bytes;
  return info;
}

std::shared_ptr<const Skeleton> AnimationStore::FindSkeleton(const std::string& id) const {
  std::shared_lock lock(mutex_);
  const auto it = skeletons_.find(id);
  return it == skeletons_.end() ? nullptr : it->second.skeleton;
}

std::shared_ptr<const CompactClip> AnimationStore::FindClip(const std::string& id) const {
  std::shared_lock lock(mutex_);
  const auto it = clips_.find(id);
  return it == clips_.end() ? nullptr : it->second.clip;
}

bool AnimationStore::DeleteSkeleton(const std::string& id) {
  std::unique_lock lock(mutex_);
  const auto it = skeletons_.find(id);
  if (it == skeletons_.end()) return false;
  bytes_ -= it->second.bytes;
  skeletons_.erase(it);
  return true;
}

bool AnimationStore::DeleteClip(const std::string& id) {
  std::unique_lock lock(mutex_);
  const auto it = clips_.find(id);
  if (it == clips_.end()) return false;
  bytes_ -= it->second.bytes;
  clips_.erase(it);
  return true;
}

uint64_t AnimationStore::bytes() const {
  std::shared_lock lock(mutex_);
  return bytes_;
}

std::size_t AnimationStore::skeleton_count() const {
  std::shared_lock lock(mutex_);
  return skeletons_.size();
}

std::size_t AnimationStore::clip_count() const {
  std::shared_lock lock(mutex_);
  return clips_.size();
}

}  // namespace skinserve::animation
