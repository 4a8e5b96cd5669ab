// MappedRegion: one client's shared-memory region as the server maps it. The file is
// opened inside the operator's --shm-dir (never through a symbolic link, never blocking:
// a FIFO or a file under another process's lease is refused), must be a regular file that
// the registering client's uid owns, is mapped shared and writable, and guarded
// (SigbusGuard) so that a client truncating its file cannot crash the server. Frames hold it by
// shared_ptr while they write; the mapping goes when the last holder lets go, and `on_unmapped`
// (set by an unregister) runs after that.
#pragma once

#include <sys/types.h>

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <utility>

#include "skinserve/model/status.h"

namespace skinserve::server {

class MappedRegion {
 public:
  // Opens `key` inside the directory `dir_fd` and maps its first `byte_size` bytes for
  // `owner`, whose uid must own the file (`file_uid`). Errors name the region, the key and
  // the sizes: INVALID_ARGUMENT (missing, not a regular file, a link, smaller than
  // byte_size), PERMISSION_DENIED (owned by another uid), FAILED_PRECONDITION (opening it
  // would block: another process holds a lease on it).
  static Result<std::shared_ptr<MappedRegion>> Open(int dir_fd, std::string name, std::string key,
                                                    uint64_t byte_size, std::string owner,
                                                    uid_t file_uid);
  MappedRegion(const MappedRegion&) = delete;
  MappedRegion& operator=(const MappedRegion&) = delete;
  ~MappedRegion();  // unguards, unmaps and closes, then runs on_unmapped

  const std::string& name() const { return name_; }
  const std::string& key() const { return key_; }
  const std::string& owner() const { return owner_; }  // RegionOwner::id of its registrar
  // The file (st_dev, st_ino): one registration per file.
  std::pair<dev_t, ino_t> file() const { return {dev_, ino_}; }
  uint64_t byte_size() const { return byte_size_; }
  std::span<std::byte> bytes() const { return {data_, byte_size_}; }

  // OK while the file still holds the mapped bytes and no write met a truncated page;
  // else FAILED_PRECONDITION naming the region and its file's size now.
  Status CheckIntact() const;
  // The same without looking at the file: only whether a write met a truncated page (the
  // guard's mark). For the frames of a stream whose region was checked whole when resolved.
  Status CheckNotBroken() const;
  // Unregistered: frames still holding it fail; `on_unmapped` runs once it is unmapped.
  void MarkRemoved(std::function<void()> on_unmapped);
  bool removed() const { return removed_.load(std::memory_order_acquire); }

  // A frame named it (at `now_ns`, steady clock): counts and resets the idle time.
  void Touch(int64_t now_ns) { last_used_ns_.store(now_ns, std::memory_order_relaxed); }
  int64_t last_used_ns() const { return last_used_ns_.load(std::memory_order_relaxed); }
  void CountFrame() { frames_.fetch_add(1, std::memory_order_relaxed); }
  uint64_t frames() const { return frames_.load(std::memory_order_relaxed); }

 private:
  MappedRegion(std::string name, std::string key, std::string owner, uint64_t byte_size)
      : name_(std::move(name)),
        key_(std::move(key)),
        owner_(std::move(owner)),
        byte_size_(byte_size) {}

  const std::string name_, key_, owner_;
  const uint64_t byte_size_;
  int fd_ = -1;
  dev_t dev_ = 0;
  ino_t ino_ = 0;
  std::byte* data_ = nullptr;
  std::size_t mapped_ = 0;  // byte_size_ rounded up to whole pages
  int guard_slot_ = -1;
  std::atomic<bool> broken_{false};  // SigbusGuard caught a write to a truncated page
  std::atomic<bool> removed_{false};
  std::atomic<int64_t> last_used_ns_{0};
  std::atomic<uint64_t> frames_{0};
  std::mutex on_unmapped_mutex_;
  std::function<void()> on_unmapped_;
};

}  // namespace skinserve::server
