#include "gpu/fd_handoff.h"

#include <fmt/format.h>
#include <poll.h>
#include <spdlog/spdlog.h>
#include <sys/random.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "security/unix_peers.h"

namespace skinserve::server {
namespace {

constexpr std::size_t kMagicBytes = sizeof(FdHandoff::kMagic) - 1;
constexpr int kReceiveTimeoutMs = 1000;  // a client that connects and sends nothing

void CloseAll(const int* fds, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) close(fds[i]);
}

void Answer(int connection, const std::string& line) {
  const std::string text = line + "\n";
  // Best effort: a client gone before the answer simply never uses its token.
  if (send(connection, text.data(), text.size(), MSG_NOSIGNAL) < 0) {
    spdlog::debug("--gpu-fd-socket: answer not sent: {}", std::strerror(errno));
  }
}

Result<std::string> NewToken() {
  uint8_t bytes[16];
  if (getrandom(bytes, sizeof(bytes), 0) != static_cast<ssize_t>(sizeof(bytes))) {
    return Internal(fmt::format("getrandom: {}", std::strerror(errno)));
  }
  std::string token;
  for (uint8_t b : bytes) token += fmt::format("{:02x}", b);
  return token;
}

// Receives the magic with exactly one fd attached; the fd, or why not (any fds closed).
Result<int> ReceiveFd(int connection) {
  pollfd ready{connection, POLLIN, 0};
  if (poll(&ready, 1, kReceiveTimeoutMs) <= 0) {
    return InvalidArgument(fmt::format("nothing received within {} ms", kReceiveTimeoutMs));
  }
  char magic[kMagicBytes + 1] = {};
  alignas(cmsghdr) char control[CMSG_SPACE(sizeof(int) * 4)] = {};
  iovec io{magic, sizeof(magic)};
  msghdr message = {};
  message.msg_iov = &io;
  message.msg_iovlen = 1;
  message.msg_control = control;
  message.msg_controllen = sizeof(control);
  const ssize_t n = recvmsg(connection, &message, MSG_CMSG_CLOEXEC | MSG_DONTWAIT);
  if (n < 0) return InvalidArgument(fmt::format("recvmsg: {}", std::strerror(errno)));
  int fds[4] = {-1, -1, -1, -1};
  std::size_t count = 0;
  for (cmsghdr* c = CMSG_FIRSTHDR(&message); c != nullptr; c = CMSG_NXTHDR(&message, c)) {
    if (c->cmsg_level != SOL_SOCKET || c->cmsg_type != SCM_RIGHTS) continue;
    const std::size_t in = (c->cmsg_len - CMSG_LEN(0)) / sizeof(int);
    for (std::size_t i = 0; i < in && count < 4; ++i) {
      std::memcpy(&fds[count++], CMSG_DATA(c) + i * sizeof(int), sizeof(int));
    }
  }
  const bool truncated = (message.msg_flags & MSG_CTRUNC) != 0;
  if (static_cast<std::size_t>(n) != kMagicBytes ||
      std::memcmp(magic, FdHandoff::kMagic, kMagicBytes) != 0 || count != 1 || truncated) {
    CloseAll(fds, count);
    return InvalidArgument(fmt::format(
        "expected the {} bytes '{}' with exactly one file descriptor (SCM_RIGHTS); got {} "
        "bytes and {} descriptor(s)",
        kMagicBytes, FdHandoff::kMagic, n,
        truncated ? std::string("too many") : std::to_string(count)));
  }
  return fds[0];
}

}  // namespace

Result<std::unique_ptr<FdHandoff>> FdHandoff::Listen(const std::string& path) {
  auto acceptor = UnixAcceptor::Listen(path, "--gpu-fd-socket " + path);
  if (!acceptor.ok()) return acceptor.status();
  auto handoff = std::unique_ptr<FdHandoff>(new FdHandoff(std::move(acceptor).value()));
  handoff->acceptor_->Start([h = handoff.get()](int connection) {
    h->Serve(connection);
    close(connection);
  });
  return handoff;
}

FdHandoff::~FdHandoff() {
  acceptor_->Stop();
  std::lock_guard lock(mutex_);
  for (auto& [token, p] : pending_) close(p.fd);
}

void FdHandoff::Serve(int connection) {
  struct ucred cred = {};
  socklen_t length = sizeof(cred);
  if (getsockopt(connection, SOL_SOCKET, SO_PEERCRED, &cred, &length) != 0) {
    Answer(connection, fmt::format("ERR SO_PEERCRED: {}", std::strerror(errno)));
    return;
  }
  const RegionOwner owner = RegionOwner::OfUnixPeer(
      UnixPeerCredentials{cred.uid, cred.gid, cred.pid, ProcessStartTicks(cred.pid)});
  Result<int> fd = ReceiveFd(connection);
  if (!fd.ok()) {
    Answer(connection, "ERR " + fd.status().message());
    return;
  }
  Result<std::string> token = Enter(*fd, owner);
  Answer(connection, token.ok() ? "OK " + *token : "ERR " + token.status().message());
}

Result<std::string> FdHandoff::Enter(int fd, const RegionOwner& owner) {
  const auto now = std::chrono::steady_clock::now();
  std::lock_guard lock(mutex_);
  ExpireLocked(now);
  std::size_t of_owner = 0;
  for (const auto& [token, p] : pending_) of_owner += p.owner == owner.id ? 1 : 0;
  Status refused;
  if (pending_.size() >= kMaxPending) {
    refused = ResourceExhausted(
        fmt::format("the server holds {} handed-over fds waiting for RegisterGpuRegion already "
                    "(each waits at most {} s)",
                    kMaxPending, kTokenSeconds));
  } else if (of_owner >= kMaxPendingPerOwner) {
    refused = ResourceExhausted(fmt::format(
        "this client has {} handed-over fds waiting for RegisterGpuRegion already; register "
        "them (or wait {} s for them to expire)",
        kMaxPendingPerOwner, kTokenSeconds));
  }
  Result<std::string> token = refused.ok() ? NewToken() : Result<std::string>(refused);
  if (!token.ok()) {
    close(fd);
    return token.status();
  }
  pending_[*token] = Pending{fd, owner.id,
                             now + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                       std::chrono::duration<double>(kTokenSeconds))};
  return token;
}

void FdHandoff::ExpireLocked(std::chrono::steady_clock::time_point now) {
  for (auto it = pending_.begin(); it != pending_.end();) {
    if (it->second.expires <= now) {
      close(it->second.fd);
      it = pending_.erase(it);
    } else {
      ++it;
    }
  }
}

Result<int> FdHandoff::Take(const std::string& token, const RegionOwner& owner) {
  std::lock_guard lock(mutex_);
  ExpireLocked(std::chrono::steady_clock::now());
  auto it = pending_.find(token);
  // Another owner's token is refused as one never handed over: it tells nothing.
  if (it == pending_.end() || it->second.owner != owner.id) {
    return FailedPrecondition(fmt::format(
        "fd_token '{}' is unknown to this client (never handed over by this process, used "
        "already, or older than {} s): hand the fd over --gpu-fd-socket again",
        token, kTokenSeconds));
  }
  const int fd = it->second.fd;
  pending_.erase(it);
  return fd;
}

std::size_t FdHandoff::pending() const {
  std::lock_guard lock(mutex_);
  return pending_.size();
}

}  // namespace skinserve::server
