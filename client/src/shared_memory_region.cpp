#include "skinserve/client/shared_memory_region.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/mman.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>

namespace skinserve::client {

Result<std::unique_ptr<SharedMemoryRegion>> SharedMemoryRegion::Create(const std::string& key,
                                                                       uint64_t byte_size,
                                                                       const std::string& dir) {
  const std::string file = !key.empty() && key[0] == '/' ? key.substr(1) : key;
  if (file.empty() || file.find('/') != std::string::npos || file == "." || file == "..") {
    return InvalidArgument(fmt::format("region key '{}' must be one file name", key));
  }
  if (byte_size == 0) return InvalidArgument("a region's byte_size must be above 0");
  std::unique_ptr<SharedMemoryRegion> region(new SharedMemoryRegion());
  region->key_ = file;
  region->path_ = dir + "/" + file;
  region->byte_size_ = byte_size;
  const int fd =
      open(region->path_.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC | O_NOFOLLOW, 0660);
  if (fd < 0) {
    const int error = errno;
    region->path_.clear();  // not ours: the destructor must not remove it
    if (error == EEXIST) {
      return AlreadyExists(fmt::format("{}/{} exists already; choose another key", dir, file));
    }
    return FailedPrecondition(
        fmt::format("cannot create {}/{}: {}", dir, file, std::strerror(error)));
  }
  const auto fail = [&](const char* what) {
    const int error = errno;
    close(fd);
    return FailedPrecondition(
        fmt::format("{} {} ({} bytes): {}", what, region->path_, byte_size, std::strerror(error)));
  };
  if (ftruncate(fd, static_cast<off_t>(byte_size)) != 0) return fail("cannot size");
  // The file's pages are allocated now, so a folder too small for the region (a container's
  // /dev/shm is 64 MB unless sized) says so here instead of failing the server's first frame
  // into it.
  if (const int error = posix_fallocate(fd, 0, static_cast<off_t>(byte_size)); error != 0) {
    errno = error;
    return fail("cannot allocate");
  }
  void* data = mmap(nullptr, byte_size, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  if (data == MAP_FAILED) return fail("cannot map");
  close(fd);  // the mapping keeps the file
  region->data_ = static_cast<std::byte*>(data);
  return region;
}

std::string SharedMemoryRegion::UniqueKey(const std::string& prefix) {
  static std::atomic<uint64_t> counter{0};
  return fmt::format("{}-{}-{}", prefix, getpid(), counter.fetch_add(1));
}

SharedMemoryRegion::~SharedMemoryRegion() {
  if (data_ != nullptr) munmap(data_, byte_size_);
  if (!path_.empty()) unlink(path_.c_str());
}

}  // namespace skinserve::client
