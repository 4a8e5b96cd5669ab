// UnixAcceptor: a Unix stream socket the server accepts on itself, on a thread of its own,
// for the doors that must know each peer (SO_PEERCRED): the unix: addresses of --listen
// (UnixListener), --gpu-fd-socket (FdHandoff) and --frame-socket (FrameSocket). A pipe wakes
// the accept loop to stop it; out of descriptors or memory, it pauses instead of spinning.
#pragma once

#include <sys/types.h>

#include <atomic>
#include <functional>
#include <memory>
#include <string>
#include <thread>

#include "skinserve/model/status.h"

namespace skinserve::server {

class UnixAcceptor {
 public:
  // Binds and listens on `path` (an existing socket file there is replaced). `what` names
  // the door in errors and logs: UNAVAILABLE "cannot listen on WHAT: why".
  static Result<std::unique_ptr<UnixAcceptor>> Listen(const std::string& path,
                                                      const std::string& what);
  ~UnixAcceptor();  // Stop()
  UnixAcceptor(const UnixAcceptor&) = delete;
  UnixAcceptor& operator=(const UnixAcceptor&) = delete;

  // Accepts connections (close-on-exec, plus `accept_flags`) and hands each to
  // `on_connection`, which owns it, on the acceptor's thread.
  void Start(std::function<void(int fd)> on_connection, int accept_flags = 0);
  // Stops accepting and joins the thread; closes the socket and removes its file if it is
  // still the one bound. Idempotent.
  void Stop();

 private:
  UnixAcceptor(std::string path, std::string what, int listen_fd, int wake_read, int wake_write,
               ino_t file_inode);
  void AcceptLoop(const std::function<void(int fd)>& on_connection, int accept_flags);

  const std::string path_, what_;
  const int listen_fd_, wake_read_, wake_write_;
  const ino_t file_inode_;
  std::thread thread_;
  std::atomic<bool> stopped_{false};
};

}  // namespace skinserve::server
