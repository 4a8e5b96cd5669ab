#include "shm/mapped_region.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <functional>

#include "shm/sigbus_guard.h"

namespace skinserve::server {

namespace {

// Why `st` (the file `key` names) may not be mapped for a client of uid `file_uid`; OK if it may.
Status CheckFile(const struct stat& st, uid_t file_uid,
                 const std::function<Status(StatusCode, std::string)>& refuse) {
  if (S_ISLNK(st.st_mode)) {
    return refuse(StatusCode::kInvalidArgument,
                  "is a symbolic link, which the server does not follow");
  }
  if (!S_ISREG(st.st_mode)) return refuse(StatusCode::kInvalidArgument, "is not a regular file");
  if (st.st_uid != file_uid) {
    return refuse(StatusCode::kPermissionDenied,
                  fmt::format("is owned by uid {}, not by uid {} (this client's): the server "
                              "maps only files their client owns",
                              st.st_uid, file_uid));
  }
  return Status::Ok();
}

}  // namespace

Result<std::shared_ptr<MappedRegion>> MappedRegion::Open(int dir_fd, std::string name,
                                                         std::string key, uint64_t byte_size,
                                                         std::string owner, uid_t file_uid) {
  std::shared_ptr<MappedRegion> region(
      new MappedRegion(std::move(name), std::move(key), std::move(owner), byte_size));
  const auto refuse = [&](StatusCode code, const std::string& why) {
    return Status(code, fmt::format("region '{}': key '{}' {}", region->name_, region->key_, why));
  };
  const auto cannot_open = [&](int error) {
    return refuse(StatusCode::kInvalidArgument,
                  fmt::format("cannot be opened for writing in the server's --shm-dir: {}",
                              std::strerror(error)));
  };
  // Looked at before it is opened (opening a device or FIFO may do something), and again
  // after, through the descriptor: the file opened is the one checked.
  struct stat before = {};
  if (fstatat(dir_fd, region->key_.c_str(), &before, AT_SYMLINK_NOFOLLOW) != 0) {
    return cannot_open(errno);
  }
  if (Status s = CheckFile(before, file_uid, refuse); !s.ok()) return s;
  // O_NONBLOCK: a FIFO swapped in meanwhile, or a lease another process holds on the file,
  // fails the open at once instead of holding a gRPC thread.
  region->fd_ =
      openat(dir_fd, region->key_.c_str(), O_RDWR | O_NOFOLLOW | O_CLOEXEC | O_NOCTTY | O_NONBLOCK);
  if (region->fd_ < 0) {
    if (errno == EWOULDBLOCK) {
      return refuse(StatusCode::kFailedPrecondition,
                    "is under a lease another process holds: opening it would block");
    }
    if (errno == ELOOP) {  // made a link after the look above
      return refuse(StatusCode::kInvalidArgument,
                    "is a symbolic link, which the server does not follow");
    }
    return cannot_open(errno);
  }
  struct stat st = {};
  if (fstat(region->fd_, &st) != 0) return cannot_open(errno);
  if (Status s = CheckFile(st, file_uid, refuse); !s.ok()) return s;
  if (st.st_dev != before.st_dev || st.st_ino != before.st_ino) {
    return refuse(StatusCode::kInvalidArgument, "was replaced while the server opened it");
  }
  region->dev_ = st.st_dev;
  region->ino_ = st.st_ino;
  if (static_cast<uint64_t>(st.st_size) < byte_size) {
    return refuse(StatusCode::kInvalidArgument,
                  fmt::format("holds {} bytes, fewer than byte_size = {}", st.st_size, byte_size));
  }
  const std::size_t page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  region->mapped_ = (byte_size + page - 1) / page * page;
  // MAP_POPULATE: the pages are mapped in now, not one fault at a time by a stream's first
  // frames (2-3 us a page on the GPU machine's Xeon, 15-18 us on the VM: a 19 MB region of
  // ticks, 4,700 pages, held its first ticks up; docs/results/2026-11-30-region-populate-vm).
  void* data = mmap(nullptr, region->mapped_, PROT_READ | PROT_WRITE, MAP_SHARED | MAP_POPULATE,
                    region->fd_, 0);
  if (data == MAP_FAILED) {
    return refuse(StatusCode::kInvalidArgument,
                  fmt::format("cannot be mapped: {}", std::strerror(errno)));
  }
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

Status MappedRegion::CheckNotBroken() const {
  if (!broken_.load(std::memory_order_acquire)) return Status::Ok();
  return FailedPrecondition(fmt::format(
      "region '{}' was truncated by its owner while the server wrote into it: its output is "
      "lost; unregister it and register a new one",
      name_));
}

Status MappedRegion::CheckIntact() const {
  if (Status s = CheckNotBroken(); !s.ok()) return s;
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
