#include "security/unix_peers.h"

#include <sys/socket.h>
#include <sys/stat.h>

#include <charconv>
#include <fstream>
#include <sstream>

namespace skinserve::server {

uint64_t ProcessStartTicks(pid_t pid) {
  if (pid <= 0) return 0;
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::stringstream text;
  text << in.rdbuf();
  const std::string stat = text.str();
  // "PID (COMM) STATE ..." where COMM may hold spaces and parentheses: fields after the
  // last ')'; starttime is field 22, the 20th after it.
  const std::size_t close = stat.rfind(')');
  if (close == std::string::npos) return 0;
  std::istringstream fields(stat.substr(close + 1));
  std::string field;
  for (int i = 0; i < 20 && fields >> field; ++i) {
  }
  uint64_t ticks = 0;
  if (!field.empty()) std::from_chars(field.data(), field.data() + field.size(), ticks);
  return ticks;
}

bool UnixPeers::Record(int fd) {
  struct ucred cred = {};
  socklen_t length = sizeof(cred);
  struct stat st = {};
  if (getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &cred, &length) != 0 || fstat(fd, &st) != 0) {
    return false;
  }
  const UnixPeerCredentials credentials{cred.uid, cred.gid, cred.pid, ProcessStartTicks(cred.pid)};
  std::lock_guard lock(mutex_);
  by_fd_[fd] = {st.st_ino, credentials};  // a closed connection's entry of this number goes
  return true;
}

std::optional<UnixPeerCredentials> UnixPeers::Find(std::string_view grpc_peer) const {
  constexpr std::string_view kPrefix = "fd:";
  if (!grpc_peer.starts_with(kPrefix)) return std::nullopt;
  int fd = -1;
  const char* end = grpc_peer.data() + grpc_peer.size();
  auto [rest, error] = std::from_chars(grpc_peer.data() + kPrefix.size(), end, fd);
  if (error != std::errc() || rest != end || fd < 0) return std::nullopt;
  std::lock_guard lock(mutex_);
  auto it = by_fd_.find(fd);
  struct stat st = {};
  if (it == by_fd_.end() || fstat(fd, &st) != 0 || !S_ISSOCK(st.st_mode) ||
      st.st_ino != it->second.socket_inode) {
    return std::nullopt;
  }
  return it->second.credentials;
}

}  // namespace skinserve::server
