#include "skinserve/client/gpu_fd_handoff.h"

#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace skinserve::client {
namespace {

constexpr char kMagic[] = "SKGPUFD1";

class Socket {
 public:
  explicit Socket(int fd) : fd_(fd) {}
  ~Socket() {
    if (fd_ >= 0) close(fd_);
  }
  int get() const { return fd_; }

 private:
  int fd_;
};

Status Unreachable(const std::string& path, const char* what) {
  return Unavailable("GPU fd handoff on " + path + ": " + what + ": " + std::strerror(errno));
}

}  // namespace

Result<std::string> HandOverGpuFd(const std::string& socket_path, int fd) {
  sockaddr_un addr = {};
  addr.sun_family = AF_UNIX;
  if (socket_path.empty() || socket_path.size() >= sizeof(addr.sun_path)) {
    return InvalidArgument("GPU fd handoff: socket path '" + socket_path +
                           "' is empty or too long");
  }
  std::memcpy(addr.sun_path, socket_path.c_str(), socket_path.size() + 1);
  Socket s(socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0));
  if (s.get() < 0) return Unreachable(socket_path, "socket");
  if (connect(s.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0) {
    return Unreachable(socket_path, "connect");
  }
  alignas(cmsghdr) char control[CMSG_SPACE(sizeof(int))] = {};
  iovec io{const_cast<char*>(kMagic), sizeof(kMagic) - 1};
  msghdr message = {};
  message.msg_iov = &io;
  message.msg_iovlen = 1;
  message.msg_control = control;
  message.msg_controllen = sizeof(control);
  cmsghdr* c = CMSG_FIRSTHDR(&message);
  c->cmsg_level = SOL_SOCKET;
  c->cmsg_type = SCM_RIGHTS;
  c->cmsg_len = CMSG_LEN(sizeof(int));
  std::memcpy(CMSG_DATA(c), &fd, sizeof(int));
  if (sendmsg(s.get(), &message, MSG_NOSIGNAL) != static_cast<ssize_t>(sizeof(kMagic) - 1)) {
    return Unreachable(socket_path, "sendmsg");
  }
  std::string line;
  char buffer[512];
  while (line.find('\n') == std::string::npos) {
    const ssize_t n = read(s.get(), buffer, sizeof(buffer));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return Unreachable(socket_path, "no answer");
    line.append(buffer, static_cast<std::size_t>(n));
  }
  line.resize(line.find('\n'));
  if (line.rfind("OK ", 0) == 0) return line.substr(3);
  const std::string why = line.rfind("ERR ", 0) == 0 ? line.substr(4) : line;
  if (why.find("waiting for RegisterGpuRegion already") != std::string::npos) {
    return ResourceExhausted("GPU fd handoff refused: " + why);
  }
  return FailedPrecondition("GPU fd handoff refused: " + why);
}

}  // namespace skinserve::client
