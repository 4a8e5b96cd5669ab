// UnixListener: a `unix:PATH` address of --listen, served by the server's own accept loop
// instead of gRPC's, so that each connection's SO_PEERCRED is known (UnixPeers): gRPC's
// peer string for a Unix socket ("unix:PATH") names the server's socket, not the client.
// Each accepted connection's credentials are recorded, then the connection is handed to
// gRPC (AddInsecureChannelFromFd), which serves it like any other: the same services,
// channel arguments (keepalive, connection age, streams per connection) and shutdown.
#pragma once

#include <grpcpp/server.h>

#include <memory>
#include <string>

#include "rpc/unix_acceptor.h"
#include "security/unix_peers.h"
#include "skinserve/model/status.h"

namespace skinserve::server {

class UnixListener {
 public:
  // Binds and listens on `address` ("unix:PATH" or "unix:///PATH"); an existing socket file
  // there is replaced, as gRPC does. UNAVAILABLE "cannot listen on ADDRESS: why".
  static Result<std::unique_ptr<UnixListener>> Listen(const std::string& address, UnixPeers* peers);
  ~UnixListener() { Stop(); }
  UnixListener(const UnixListener&) = delete;
  UnixListener& operator=(const UnixListener&) = delete;

  // Accepts connections on a thread of its own and hands them to `server` (built and
  // started, outliving Stop()).
  void Start(grpc::Server* server);
  // Stops accepting and joins the thread; then closes the socket and removes its file.
  // Connections already handed over stay gRPC's. Idempotent.
  void Stop() { acceptor_->Stop(); }

 private:
  UnixListener(std::string address, std::unique_ptr<UnixAcceptor> acceptor, UnixPeers* peers)
      : address_(std::move(address)), acceptor_(std::move(acceptor)), peers_(peers) {}

  const std::string address_;
  const std::unique_ptr<UnixAcceptor> acceptor_;
  UnixPeers* const peers_;
};

}  // namespace skinserve::server
