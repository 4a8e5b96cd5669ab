#include "socket/frame_socket.h"

#include <fmt/format.h>
#include <sys/socket.h>

#include <cerrno>
#include <cstring>

namespace skinserve::server {

Result<std::unique_ptr<FrameSocket>> FrameSocket::Listen(const Options& options, AccessFor access) {
  auto acceptor = UnixAcceptor::Listen(options.path, "--frame-socket " + options.path);
  if (!acceptor.ok()) return acceptor.status();
  auto socket = std::unique_ptr<FrameSocket>(
      new FrameSocket(options, std::move(access), std::move(acceptor).value()));
  socket->acceptor_->Start([s = socket.get()](int fd) { s->Accept(fd); });
  return socket;
}

FrameSocket::FrameSocket(Options options, AccessFor access, std::unique_ptr<UnixAcceptor> acceptor)
    : options_(std::move(options)), access_(std::move(access)), acceptor_(std::move(acceptor)) {}

FrameSocket::~FrameSocket() { Stop(); }

void FrameSocket::Stop() {
  if (stopped_.exchange(true)) return;
  acceptor_->Stop();  // no connection comes any more; the socket file goes
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
  });
}

void FrameSocket::JoinFinishedLocked() {
  for (auto it = open_.begin(); it != open_.end();) {
    if (!it->connection) {  // its thread unlocked the mutex as its last step
      it->thread.join();
      it = open_.erase(it);
    } else {
      ++it;
    }
  }
}

}  // namespace skinserve::server
