// UnixPeers: who is at the other end of each Unix-socket connection the server accepted
// itself (UnixListener): the kernel's SO_PEERCRED (uid, gid, pid) read at accept, before
// gRPC gets the connection. gRPC names such a connection "fd:N" (its peer string), so the
// table is keyed by N; a connection's number is reused once gRPC closes it, so each entry
// also holds its socket's inode, and a lookup whose fd N is not that socket finds nothing.
// gRPC 1.51 keeps a connection's fd open while any call on it lives (its transport owns
// the endpoint until the last call is gone: checked with a client killed mid-call), so a
// call that looks up its own peer while it runs finds its own connection's entry.
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>

namespace skinserve::server {

struct UnixPeerCredentials {
  uid_t uid = 0;
  gid_t gid = 0;
  pid_t pid = 0;  // 0: the client's process is in a pid namespace the server cannot see
  // The process's start time (/proc/PID/stat, clock ticks since boot): with the pid, one
  // process over the host's uptime (a pid alone is reused); 0 when pid is 0 or unreadable.
  uint64_t start_ticks = 0;
};

class UnixPeers {
 public:
  // Reads SO_PEERCRED of the accepted socket `fd` and records it; false (errno set) if
  // the kernel does not say.
  bool Record(int fd);
  // The credentials of the connection gRPC calls `grpc_peer` ("fd:N"); none for any other
  // peer (TCP, or a connection this table does not hold).
  std::optional<UnixPeerCredentials> Find(std::string_view grpc_peer) const;

 private:
  struct Entry {
    ino_t socket_inode = 0;
    UnixPeerCredentials credentials;
  };
  mutable std::mutex mutex_;
  std::map<int, Entry> by_fd_;
};

// The start time of process `pid` (field 22 of /proc/PID/stat); 0 if it cannot be read.
uint64_t ProcessStartTicks(pid_t pid);

}  // namespace skinserve::server
