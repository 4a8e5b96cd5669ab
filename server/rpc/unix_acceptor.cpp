#include "rpc/unix_acceptor.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <poll.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace skinserve::server {

Result<std::unique_ptr<UnixAcceptor>> UnixAcceptor::Listen(const std::string& path,
                                                           const std::string& what) {
  const auto fail = [&](const std::string& why) {
    return Unavailable(fmt::format("cannot listen on {}: {}", what, why));
  };
  sockaddr_un addr = {};
  addr.sun_family = AF_UNIX;
  if (path.empty() || path.size() >= sizeof(addr.sun_path)) {
    return fail(fmt::format("the path must be 1 to {} bytes", sizeof(addr.sun_path) - 1));
  }
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  struct stat existing = {};
  if (lstat(path.c_str(), &existing) == 0 && S_ISSOCK(existing.st_mode)) unlink(path.c_str());
  const int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (fd < 0) return fail(std::strerror(errno));
  int wake[2] = {-1, -1};
  struct stat bound = {};
  if (bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0 ||
      listen(fd, SOMAXCONN) != 0 || stat(path.c_str(), &bound) != 0 ||
      pipe2(wake, O_CLOEXEC) != 0) {
    const std::string why = std::strerror(errno);
    close(fd);
    return fail(why);
  }
  return std::unique_ptr<UnixAcceptor>(
      new UnixAcceptor(path, what, fd, wake[0], wake[1], bound.st_ino));
}

UnixAcceptor::UnixAcceptor(std::string path, std::string what, int listen_fd, int wake_read,
                           int wake_write, ino_t file_inode)
    : path_(std::move(path)),
      what_(std::move(what)),
      listen_fd_(listen_fd),
      wake_read_(wake_read),
      wake_write_(wake_write),
      file_inode_(file_inode) {}

UnixAcceptor::~UnixAcceptor() {
  Stop();
  close(wake_read_);
  close(wake_write_);
}

void UnixAcceptor::Start(std::function<void(int fd)> on_connection, int accept_flags) {
  thread_ = std::thread([this, on_connection = std::move(on_connection), accept_flags] {
    AcceptLoop(on_connection, accept_flags);
  });
}

void UnixAcceptor::Stop() {
  if (stopped_.exchange(true)) return;
  const char byte = 0;
  while (write(wake_write_, &byte, 1) < 0 && errno == EINTR) {
  }
  if (thread_.joinable()) thread_.join();
  close(listen_fd_);
  struct stat now = {};
  if (stat(path_.c_str(), &now) == 0 && now.st_ino == file_inode_) unlink(path_.c_str());
}

void UnixAcceptor::AcceptLoop(const std::function<void(int fd)>& on_connection, int accept_flags) {
  pollfd fds[2] = {{listen_fd_, POLLIN, 0}, {wake_read_, POLLIN, 0}};
  while (true) {
    if (poll(fds, 2, -1) < 0 && errno != EINTR) {
      spdlog::error("{}: no longer accepting connections: poll: {}", what_, std::strerror(errno));
      return;
    }
    if (fds[1].revents != 0) return;  // Stop()
    if ((fds[0].revents & POLLIN) == 0) continue;
    const int fd = accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC | accept_flags);
    if (fd < 0) {
      if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR || errno == ECONNABORTED) {
        continue;
      }
      // Out of file descriptors or memory: the connection waits in the backlog; retry
      // after a pause rather than spin, unless stopped meanwhile.
      spdlog::warn("{}: cannot accept a connection: {}", what_, std::strerror(errno));
      if (poll(&fds[1], 1, 100) > 0) return;
      continue;
    }
    on_connection(fd);
  }
}

}  // namespace skinserve::server
