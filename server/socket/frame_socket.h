// FrameSocket: the frame socket (--frame-socket PATH, docs/serving/frame-socket.md), where
// same-host clients send StreamSkin's requests without gRPC (wire/frame_socket_protocol.h).
// Its purpose is the small frame's cost: over gRPC a 25k-vertex frame is read, skinned and
// written by three threads that wake each other (gRPC's callback threads, 8-12 context
// switches a frame); here one thread per connection reads it, skins it (when a compute
// thread is free) and writes the answer, and sleeps only waiting for the next request.
// The server accepts the socket itself, so each connection's peer is known (SO_PEERCRED):
// its regions are the ones it registered over gRPC from the same process, and the
// authorization policy's rules for StreamSkin apply to it as to an unauthenticated client.
// At most --frame-socket-max-connections are open; one more is refused RESOURCE_EXHAUSTED.
#pragma once

#include <atomic>
#include <functional>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "rpc/unix_acceptor.h"
#include "security/unix_peers.h"
#include "skinserve/model/status.h"
#include "socket/frame_socket_access.h"
#include "socket/frame_socket_connection.h"

namespace skinserve::server {

class FrameSocket {
 public:
  struct Options {
    std::string path;
    std::size_t max_connections = 256;
    double idle_seconds = 120;  // --stream-idle-seconds
  };
  // What a connection from `peer` serves with (the service's, SkinningService).
  using AccessFor = std::function<FrameSocketAccess(const UnixPeerCredentials& peer)>;

  // Binds and listens on options.path (an existing socket file there is replaced) and
  // starts accepting. UNAVAILABLE "cannot listen on --frame-socket PATH: why".
  static Result<std::unique_ptr<FrameSocket>> Listen(const Options& options, AccessFor access);
  ~FrameSocket();  // Stop()
  FrameSocket(const FrameSocket&) = delete;
  FrameSocket& operator=(const FrameSocket&) = delete;

  // Stops accepting, drains every connection (each answers the request it is serving, then
  // ends UNAVAILABLE) and waits for them; removes the socket file. Idempotent.
  void Stop();

 private:
  struct Open {
    std::unique_ptr<FrameSocketConnection> connection;  // null once it ended (under mutex_)
    std::thread thread;  // ended, or about to, once connection is null
  };
  FrameSocket(Options options, AccessFor access, std::unique_ptr<UnixAcceptor> acceptor);
  void Accept(int fd);  // on the acceptor's thread
  void JoinFinishedLocked();

  const Options options_;
  const AccessFor access_;
  const std::unique_ptr<UnixAcceptor> acceptor_;
  std::atomic<bool> stopped_{false};
  mutable std::mutex mutex_;
  std::list<Open> open_;
};

}  // namespace skinserve::server
