#include "rpc/unix_listener.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <grpcpp/server_posix.h>
#include <poll.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace skinserve::server {
namespace {

// gRPC's spellings: "unix:relative/or/absolute" and "unix:///absolute".
std::string PathOf(const std::string& address) {
  std::string path = address.substr(5);
  if (path.starts_with("//")) path = path.substr(2);
  return path;
}

}  // namespace

Result<std::unique_ptr<UnixListener>> UnixListener::Listen(const std::string& address,
                                                           UnixPeers* peers) {
  const std::string path = PathOf(address);
  const auto fail = [&](const std::string& why) {
    return Unavailable(fmt::format("cannot listen on {}: {}", address, why));
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
  return std::unique_ptr<UnixListener>(
      new UnixListener(address, path, fd, wake[0], wake[1], bound.st_ino, peers));
}

UnixListener::UnixListener(std::string address, std::string path, int listen_fd, int wake_read,
                           int wake_write, ino_t file_inode, UnixPeers* peers)
    : address_(std::move(address)),
      path_(std::move(path)),
      listen_fd_(listen_fd),
      wake_read_(wake_read),
      wake_write_(wake_write),
      file_inode_(file_inode),
      peers_(peers) {}

UnixListener::~UnixListener() {
  Stop();
  close(wake_read_);
  close(wake_write_);
}

void UnixListener::Start(grpc::Server* server) {
  thread_ = std::thread([this, server] { AcceptLoop(server); });
}

void UnixListener::Stop() {
  if (stopped_.exchange(true)) return;
  const char byte = 0;
  while (write(wake_write_, &byte, 1) < 0 && errno == EINTR) {
  }
  if (thread_.joinable()) thread_.join();
  close(listen_fd_);
  struct stat now = {};
  if (stat(path_.c_str(), &now) == 0 && now.st_ino == file_inode_) unlink(path_.c_str());
}

void UnixListener::AcceptLoop(grpc::Server* server) {
  pollfd fds[2] = {{listen_fd_, POLLIN, 0}, {wake_read_, POLLIN, 0}};
  while (true) {
    if (poll(fds, 2, -1) < 0 && errno != EINTR) {
      spdlog::error("{}: no longer accepting connections: poll: {}", address_,
                    std::strerror(errno));
      return;
    }
    if (fds[1].revents != 0) return;  // Stop()
    if ((fds[0].revents & POLLIN) == 0) continue;
    const int fd = accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
    if (fd < 0) {
      if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR || errno == ECONNABORTED) {
        continue;
      }
      // Out of file descriptors or memory: the connection waits in the backlog; retry
      // after a pause rather than spin, unless stopped meanwhile.
      spdlog::warn("{}: cannot accept a connection: {}", address_, std::strerror(errno));
      if (poll(&fds[1], 1, 100) > 0) return;
      continue;
    }
    // Recorded before gRPC sees the connection: its first call finds its credentials.
    if (!peers_->Record(fd)) {
      spdlog::warn("{}: connection refused: its credentials (SO_PEERCRED) cannot be read: {}",
                   address_, std::strerror(errno));
      close(fd);
      continue;
    }
    grpc::AddInsecureChannelFromFd(server, fd);
  }
}

}  // namespace skinserve::server
