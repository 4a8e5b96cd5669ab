#include "mapped_region.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "sigbus_guard.h"

namespace skinserve::server {

Result<std::shared_ptr<MappedRegion>> MappedRegion::Open(int dir_fd, std::string name,
                                                         std::string key, uint64_t byte_size,
                                                         std::string owner) {
  std::shared_ptr<MappedRegion> region(
      new MappedRegion(std::move(name), std::move(key), std::move(owner), byte_size));
  const auto refuse = [&](const std::string& why) {
    return InvalidArgument(
        fmt::format("region '{}': key '{}' {}", region->name_, region->key_, why));
  };
  region->fd_ = openat(dir_fd, region->key_.c_str(), O_RDWR | O_NOFOLLOW | O_CLOEXEC | O_NOCTTY);
  if (region->fd_ < 0) {
    return refuse(errno == ELOOP ? "is a symbolic link, which the server does not follow"
                                 : fmt::format("cannot be opened for writing in the server's "
                                               "--shm-dir: {}",
                                               std::strerror(errno)));
  }
  struct stat st = {};
  if (fstat(region->fd_, &st) != 0) return refuse(std::strerror(errno));
  if (!S_ISREG(st.st_mode)) return refuse("is not a regular file");
  if (static_cast<uint64_t>(st.st_size) < byte_size) {
    return refuse(fmt::format("holds {} bytes, fewer than byte_size = {}", st.st_size, byte_size));
  }
  const std::size_t page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  region->mapped_ = (byte_size + page - 1) / page * page;
  void* data = mmap(nullptr, region->mapped_, PROT_READ | PROT_WRITE, MAP_SHARED, region->fd_, 0);
  if (data == MAP_FAILED) return refuse(fmt::format("cannot be mapped: {}", std::strerror(errno)));
  region->data_ = static_cast<std::byte*>(data);
  SigbusGuard::Install();
  region->guard_slot_ = SigbusGuard::Add(data, region->mapped_, &region->broken_);
  if (region->guard_slot_ < 0) {
    return ResourceExhausted(fmt::format("region '{}': the server guards at most {} mappings",
                                         region->name_, SigbusGuard::kMaxRanges));
  }
  return region;
}

MappedRegion::~MappedRegion() {
  SigbusGuard::Remove(guard_slot_);
  if (data_ != nullptr) munmap(data_, mapped_);
  if (fd_ >= 0) close(fd_);
  std::function<void()> done;
  {
    std::lock_guard lock(on_unmapped_mutex_);
    done = std::move(on_unmapped_);
  }
  if (done) done();
}

Status MappedRegion::CheckIntact() const {
  if (broken_.load(std::memory_order_acquire)) {
    return FailedPrecondition(fmt::format(
        "region '{}' was truncated by its owner while the server wrote into it: its output is "
        "lost; unregister it and register a new one",
        name_));
  }
  struct stat st = {};
  if (fstat(fd_, &st) != 0 || static_cast<uint64_t>(st.st_size) < byte_size_) {
    return FailedPrecondition(fmt::format(
        "region '{}': its file '{}' now holds {} bytes, fewer than the {} registered (truncated "
        "by its owner); unregister it and register a new one",
        name_, key_, st.st_size, byte_size_));
  }
  return Status::Ok();
}

void MappedRegion::MarkRemoved(std::function<void()> on_unmapped) {
  {
    std::lock_guard lock(on_unmapped_mutex_);
    on_unmapped_ = std::move(on_unmapped);
  }
  removed_.store(true, std::memory_order_release);
}

}  // namespace skinserve::server
