// MeshStore: meshes by content id under a byte budget, least-recently-used eviction that
// never touches a mesh a frame is using, and each backend's prepared copy of each mesh.
#pragma once

#include <atomic>
#include <cstdint>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>
#include <vector>

#include "skinserve/engine/backend.h"
#include "skinserve/model/mesh.h"
#include "skinserve/model/status.h"

namespace skinserve {

class MeshStore {
 public:
  // One slot per backend for its prepared copy, filled on the first frame that needs it.
  class Entry {
   public:
    Entry(std::shared_ptr<const Mesh> mesh, std::size_t backend_count)
        : mesh_(std::move(mesh)), prepared_(backend_count) {}
    const std::shared_ptr<const Mesh>& mesh() const { return mesh_; }
    // False once the mesh was deleted or evicted: a kept plan (Engine::Reuse) that still
    // holds the entry must not skin it any more.
    bool stored() const { return stored_.load(std::memory_order_acquire); }
    // A kept plan used the entry without Acquire: it counts as recently used at the next
    // eviction (a second chance, instead of a move in the LRU list under the store's lock).
    void MarkUsed() {
      if (!used_.load(std::memory_order_relaxed)) used_.store(true, std::memory_order_relaxed);
    }
    // The backend's resident copy, prepared once (later callers wait for the first);
    // `*built` is set when this call prepared it.
    Result<const PreparedMesh*> Prepared(std::size_t backend_index, Backend& backend,
                                         bool* built = nullptr);

   private:
    friend class MeshStore;
    std::shared_ptr<const Mesh> mesh_;
    std::atomic<bool> stored_{true};
    std::atomic<bool> used_{false};
    std::mutex prepare_mutex_;
    std::vector<std::unique_ptr<PreparedMesh>> prepared_;
  };
  // Holding a Lease pins its entry: eviction and deletion leave it alone until released.
  using Lease = std::shared_ptr<Entry>;

  MeshStore(uint64_t budget_bytes, std::size_t backend_count)
      : budget_bytes_(budget_bytes), backend_count_(backend_count) {}

  // Stores `mesh` unless its id is stored already (then *already_stored is set), evicting
  // unpinned meshes least recently used first. RESOURCE_EXHAUSTED when it cannot fit.
  Status Insert(std::shared_ptr<const Mesh> mesh, bool* already_stored);
  // The entry for `id`, pinned and marked most recently used; nullptr if absent.
  Lease Acquire(const std::string& id);
  // Forgets `id`; a frame in flight keeps its pinned entry alive until it finishes.
  bool Erase(const std::string& id);
  // Whether a mesh of `bytes` could be stored at all (budget), before it is built.
  Status CheckFits(uint64_t bytes) const;

  std::size_t count() const;
  uint64_t bytes() const;
  uint64_t budget_bytes() const { return budget_bytes_; }
  uint64_t evictions() const;

 private:
  struct Slot {
    Lease entry;
    std::list<std::string>::iterator lru;  // position in lru_, front = most recent
  };
  const uint64_t budget_bytes_;
  const std::size_t backend_count_;
  mutable std::mutex mutex_;
  // Moves the entries kept plans used since the last eviction (Entry::MarkUsed) to the
  // most recent end. Under mutex_.
  void PromoteUsedLocked();
  // Forgets slot `it` (erased or evicted). Under mutex_.
  void RemoveLocked(std::unordered_map<std::string, Slot>::iterator it);

  std::unordered_map<std::string, Slot> slots_;
  std::list<std::string> lru_;
  uint64_t bytes_ = 0;
  uint64_t evictions_ = 0;
};

}  // namespace skinserve
