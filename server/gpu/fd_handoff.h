// FdHandoff: the GPU regions' side socket (--gpu-fd-socket PATH, docs/serving/gpu-regions.md).
// gRPC cannot carry a file descriptor, so a client hands its exported GPU buffer's opaque
// fd over a Unix socket of its own with SCM_RIGHTS: it connects, sends the 8 bytes
// "SKGPUFD1" with one descriptor attached, and reads one line back, "OK TOKEN" or
// "ERR why". The server accepts that socket itself, so it knows the sender's process
// (SO_PEERCRED, as UnixListener does for gRPC's connections): a token is good once, only
// for a gRPC call from that same process (RegionOwner), and for kTokenSeconds. The fds
// waiting for their RegisterGpuRegion are bounded in all and per owner, and closed when
// their token expires.
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "rpc/unix_acceptor.h"
#include "shm/region_owner.h"
#include "skinserve/model/status.h"

namespace skinserve::server {

class FdHandoff {
 public:
  static constexpr char kMagic[] = "SKGPUFD1";  // 8 bytes, without the NUL
  static constexpr double kTokenSeconds = 30;
  static constexpr std::size_t kMaxPending = 64;
  static constexpr std::size_t kMaxPendingPerOwner = 8;

  // Binds and listens on `path` (an existing socket file there is replaced) and starts
  // the accept thread. UNAVAILABLE "cannot listen on --gpu-fd-socket PATH: why".
  static Result<std::unique_ptr<FdHandoff>> Listen(const std::string& path);
  ~FdHandoff();  // stops the thread, closes every pending fd, removes the socket file
  FdHandoff(const FdHandoff&) = delete;
  FdHandoff& operator=(const FdHandoff&) = delete;

  // The fd handed over under `token` by `owner`, now the caller's to close. A token that
  // is unknown, used, expired or another owner's: FAILED_PRECONDITION, the same for each.
  Result<int> Take(const std::string& token, const RegionOwner& owner);
  std::size_t pending() const;

 private:
  struct Pending {
    int fd = -1;
    std::string owner;
    std::chrono::steady_clock::time_point expires;
  };
  explicit FdHandoff(std::unique_ptr<UnixAcceptor> acceptor) : acceptor_(std::move(acceptor)) {}
  // One connection: the fd received and a token answered, or an error line.
  void Serve(int connection);
  // The token for `fd` of `owner`, or why it is refused (the fd is then closed).
  Result<std::string> Enter(int fd, const RegionOwner& owner);
  void ExpireLocked(std::chrono::steady_clock::time_point now);

  const std::unique_ptr<UnixAcceptor> acceptor_;  // its thread serves each connection
  mutable std::mutex mutex_;
  std::map<std::string, Pending> pending_;  // by token
};

}  // namespace skinserve::server
