#include "rpc/unix_listener.h"

#include <grpcpp/server_posix.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
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
  auto acceptor = UnixAcceptor::Listen(PathOf(address), address);
  if (!acceptor.ok()) return acceptor.status();
  return std::unique_ptr<UnixListener>(
      new UnixListener(address, std::move(acceptor).value(), peers));
}

void UnixListener::Start(grpc::Server* server) {
  // gRPC takes non-blocking descriptors.
  acceptor_->Start(
      [this, server](int fd) {
        // Recorded before gRPC sees the connection: its first call finds its credentials.
        if (!peers_->Record(fd)) {
          spdlog::warn("{}: connection refused: its credentials (SO_PEERCRED) cannot be read: {}",
                       address_, std::strerror(errno));
          close(fd);
          return;
        }
        grpc::AddInsecureChannelFromFd(server, fd);
      },
      SOCK_NONBLOCK);
}

}  // namespace skinserve::server
