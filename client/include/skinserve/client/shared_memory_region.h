// SharedMemoryRegion: memory this process shares with a skinserve on the same host (the
// same-host data plane, docs/serving/shared-memory.md). It creates a file inside the server's
// --shm-dir (by default /dev/shm, where POSIX shared-memory objects live), sizes it and
// maps it; register it with SkinClient::RegisterRegion and name it in SkinOptions::output,
// and the server skins straight into it. The file is removed when the region is
// destroyed; the server's mapping lasts until it is unregistered (or idle too long).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "skinserve/model/status.h"

namespace skinserve::client {

class SharedMemoryRegion {
 public:
  // Creates `key` (one file name; a leading "/" as in POSIX shared-memory names is
  // dropped) inside `dir` with `byte_size` bytes, zeroed, allocated (FAILED_PRECONDITION
  // naming the file when its file system cannot hold them) and mapped. An existing file of
  // that name is an error (ALREADY_EXISTS): keys are chosen per process, see UniqueKey.
  static Result<std::unique_ptr<SharedMemoryRegion>> Create(const std::string& key,
                                                            uint64_t byte_size,
                                                            const std::string& dir = "/dev/shm");
  // A key no other live process uses: `prefix`-<pid>-<counter>.
  static std::string UniqueKey(const std::string& prefix = "skinserve");

  SharedMemoryRegion(const SharedMemoryRegion&) = delete;
  SharedMemoryRegion& operator=(const SharedMemoryRegion&) = delete;
  ~SharedMemoryRegion();  // unmaps and removes the file

  const std::string& key() const { return key_; }    // as the server's RegisterRegion wants it
  const std::string& path() const { return path_; }  // the file
  uint64_t byte_size() const { return byte_size_; }
  std::span<std::byte> bytes() const { return {data_, byte_size_}; }

 private:
  SharedMemoryRegion() = default;
  std::string key_, path_;
  uint64_t byte_size_ = 0;
  std::byte* data_ = nullptr;
};

}  // namespace skinserve::client
