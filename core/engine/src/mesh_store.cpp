#include "mesh_store.h"

#include <fmt/format.h>

namespace skinserve {

Result<const PreparedMesh*> MeshStore::Entry::Prepared(std::size_t backend_index, Backend& backend,
                                                       bool* built) {
  std::lock_guard lock(prepare_mutex_);
  auto& slot = prepared_.at(backend_index);
  if (!slot) {
    auto prepared = backend.Prepare(mesh_);
    if (built != nullptr) *built = true;  // even when it failed: it may have compiled
    if (!prepared.ok()) return prepared.status();
    slot = std::move(prepared).value();
  }
  return static_cast<const PreparedMesh*>(slot.get());
}

Status MeshStore::CheckFits(uint64_t bytes) const {
  if (bytes <= budget_bytes_) return Status::Ok();
  return ResourceExhausted(
      fmt::format("the mesh needs {} bytes; the mesh budget is {} bytes", bytes, budget_bytes_));
}

Status MeshStore::Insert(std::shared_ptr<const Mesh> mesh, bool* already_stored) {
  const uint64_t bytes = mesh->byte_size();
  if (Status s = CheckFits(bytes); !s.ok()) return s;
  std::lock_guard lock(mutex_);
  if (auto it = slots_.find(mesh->id()); it != slots_.end()) {
    lru_.splice(lru_.begin(), lru_, it->second.lru);
    *already_stored = true;
    return Status::Ok();
  }
  *already_stored = false;
  if (bytes_ + bytes > budget_bytes_) PromoteUsedLocked();
  // Evict from the least recently used end, skipping pinned entries (use_count > 1: a
  // lease is out). A stale count only errs towards keeping a mesh.
  for (auto it = lru_.end(); bytes_ + bytes > budget_bytes_ && it != lru_.begin();) {
    --it;
    auto slot = slots_.find(*it);
    if (slot->second.entry.use_count() > 1) continue;
    ++it;  // RemoveLocked erases the slot's place in lru_
    RemoveLocked(slot);
    ++evictions_;
  }
  if (bytes_ + bytes > budget_bytes_) {
    return ResourceExhausted(fmt::format(
        "the mesh needs {} bytes; {} of the {}-byte mesh budget are held by meshes in use", bytes,
        bytes_, budget_bytes_));
  }
  lru_.push_front(mesh->id());
  Slot slot{std::make_shared<Entry>(mesh, backend_count_), lru_.begin()};
  slots_.emplace(mesh->id(), std::move(slot));
  bytes_ += bytes;
  return Status::Ok();
}

MeshStore::Lease MeshStore::Acquire(const std::string& id) {
  std::lock_guard lock(mutex_);
  auto it = slots_.find(id);
  if (it == slots_.end()) return nullptr;
  lru_.splice(lru_.begin(), lru_, it->second.lru);
  return it->second.entry;
}

bool MeshStore::Erase(const std::string& id) {
  std::lock_guard lock(mutex_);
  auto it = slots_.find(id);
  if (it == slots_.end()) return false;
  RemoveLocked(it);
  return true;
}

void MeshStore::RemoveLocked(std::unordered_map<std::string, Slot>::iterator it) {
  it->second.entry->stored_.store(false, std::memory_order_release);
  bytes_ -= it->second.entry->mesh()->byte_size();
  lru_.erase(it->second.lru);
  slots_.erase(it);
}

void MeshStore::PromoteUsedLocked() {
  for (auto it = lru_.begin(); it != lru_.end();) {
    const auto next = std::next(it);
    Entry& entry = *slots_.at(*it).entry;
    if (entry.used_.exchange(false, std::memory_order_relaxed)) {
      lru_.splice(lru_.begin(), lru_, it);
    }
    it = next;
  }
}

std::size_t MeshStore::count() const {
  std::lock_guard lock(mutex_);
  return slots_.size();
}

uint64_t MeshStore::bytes() const {
  std::lock_guard lock(mutex_);
  return bytes_;
}

uint64_t MeshStore::evictions() const {
  std::lock_guard lock(mutex_);
  return evictions_;
}

}  // namespace skinserve
