#include "socket/frame_socket.h"

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

Result<std::unique_ptr<FrameSocket>> FrameSocket::Listen(const Options& options, AccessFor access) {
  const auto fail = [&](const std::string& why) {
    return Unavailable(fmt::format("cannot listen on --frame-socket {}: {}", options.path, why));
  };
  sockaddr_un addr = {};
  addr.sun_family = AF_UNIX;
  if (options.path.empty() || options.path.size() >= sizeof(addr.sun_path)) {
    return fail(fmt::format("the path must be 1 to {} bytes", sizeof(addr.sun_path) - 1));
  }
  std::memcpy(addr.sun_path, options.path.c_str(), options.path.size() + 1);
  struct stat existing = {};
  if (lstat(options.path.c_str(), &existing) == 0 && S_ISSOCK(existing.st_mode)) {
    unlink(options.path.c_str());
  }
  const int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (fd < 0) return fail(std::strerror(errno));
  int wake[2] = {-1, -1};
  if (bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0 ||
      listen(fd, SOMAXCONN) != 0 || pipe2(wake, O_CLOEXEC) != 0) {
    const std::string why = std::strerror(errno);
    close(fd);
    return fail(why);
  }
  auto socket = std::unique_ptr<FrameSocket>(
      new FrameSocket(options, std::move(access), fd, wake[0], wake[1]));
  socket->thread_ = std::thread([s = socket.get()] { s->AcceptLoop(); });
  return socket;
}

FrameSocket::FrameSocket(Options options, AccessFor access, int listen_fd, int wake_read,
                         int wake_write)
    : options_(std::move(options)),
      access_(std::move(access)),
      listen_fd_(listen_fd),
      wake_read_(wake_read),
      wake_write_(wake_write) {}

FrameSocket::~FrameSocket() {
  Stop();
  close(listen_fd_);
  close(wake_read_);
  close(wake_write_);
}

void FrameSocket::Stop() {
  if (stopped_.exchange(true)) return;
  const char byte = 0;
  while (write(wake_write_, &byte, 1) < 0 && errno == EINTR) {
  }
  if (thread_.joinable()) thread_.join();
  unlink(options_.path.c_str());
  {
    std::lock_guard lock(mutex_);
    for (Open& open : open_) {
      if (open.connection) open.connection->Drain();
    }
  }
  // The accept loop is gone: nothing adds to open_ any more.
  for (Open& open : open_) open.thread.join();
  open_.clear();
}

void FrameSocket::AcceptLoop() {
  pollfd fds[2] = {{listen_fd_, POLLIN, 0}, {wake_read_, POLLIN, 0}};
  while (true) {
    if (poll(fds, 2, -1) < 0 && errno != EINTR) {
      spdlog::error("--frame-socket {}: no longer accepting: poll: {}", options_.path,
                    std::strerror(errno));
      return;
    }
    if (fds[1].revents != 0) return;
    if ((fds[0].revents & POLLIN) == 0) continue;
    const int fd = accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC);
    if (fd < 0) {
      if (errno != EAGAIN && errno != EINTR && errno != ECONNABORTED) {
        spdlog::warn("--frame-socket {}: accept: {}", options_.path, std::strerror(errno));
        if (poll(&fds[1], 1, 100) > 0) return;  // e.g. out of fds: not a busy loop
      }
      continue;
    }
    Accept(fd);
  }
}

void FrameSocket::Accept(int fd) {
  struct ucred cred = {};
  socklen_t length = sizeof(cred);
  FrameSocketAccess access;
  if (getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &cred, &length) == 0) {
    access = access_({cred.uid, cred.gid, cred.pid, ProcessStartTicks(cred.pid)});
  } else {
    access.allowed = Internal(fmt::format("SO_PEERCRED: {}", std::strerror(errno)));
  }
  std::lock_guard lock(mutex_);
  JoinFinishedLocked();
  Open& open = open_.emplace_back();
  open.connection =
      std::make_unique<FrameSocketConnection>(fd, std::move(access), options_.idle_seconds);
  if (open_.size() > options_.max_connections) {
    if (FrameSocketCounters* c = open.connection->counters()) c->refused.fetch_add(1);
    open.connection->Refuse(ResourceExhausted(
        fmt::format("{} frame-socket connections are open, the most "
                    "--frame-socket-max-connections allows; close one or use gRPC",
                    options_.max_connections)));
    open_.pop_back();
    return;
  }
  if (FrameSocketCounters* c = open.connection->counters()) c->connections.fetch_add(1);
  open.thread = std::thread([this, &open] {
    open.connection->Serve();
    if (FrameSocketCounters* c = open.connection->counters()) c->connections.fetch_sub(1);
    std::lock_guard ended(mutex_);
    open.connection.reset();  // its fd, buffers and budget go now, not at the next accept
    open.finished.store(true);
  });
}

void FrameSocket::JoinFinishedLocked() {
  for (auto it = open_.begin(); it != open_.end();) {
    if (it->finished.load()) {
      it->thread.join();
      it = open_.erase(it);
    } else {
      ++it;
    }
  }
}

}  // namespace skinserve::server
