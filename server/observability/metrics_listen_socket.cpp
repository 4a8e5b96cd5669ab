#include "observability/metrics_listen_socket.h"

#include <fmt/format.h>
#include <netdb.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstring>

#include "observability/metrics_port_limits.h"

namespace skinserve::server {

namespace {

struct HostPort {
  std::string host;
  int port = -1;
};

Result<HostPort> ParseListen(const std::string& listen) {
  const std::size_t colon = listen.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == listen.size()) {
    return InvalidArgument(fmt::format("--metrics-listen '{}': expected host:port", listen));
  }
  HostPort out;
  out.host = listen.substr(0, colon);
  if (out.host.size() >= 2 && out.host.front() == '[' && out.host.back() == ']') {
    out.host = out.host.substr(1, out.host.size() - 2);
  }
  const char* begin = listen.data() + colon + 1;
  const char* end = listen.data() + listen.size();
  const auto [ptr, ec] = std::from_chars(begin, end, out.port);
  if (ec != std::errc() || ptr != end || out.port < 0 || out.port > 65535) {
    return InvalidArgument(
        fmt::format("--metrics-listen '{}': the port must be a number 0..65535", listen));
  }
  return out;
}

// One resolved address bound and listening, or -1 with errno set.
int BindAndListen(const addrinfo& a) {
  const int fd = socket(a.ai_family, a.ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, a.ai_protocol);
  if (fd < 0) return -1;
  const int yes = 1, no = 0, receive_buffer = metrics_port::kReceiveBufferBytes;
  // Accepted connections inherit the receive buffer, which also caps the window the
  // server advertises: a sender parks at most that much in kernel memory.
  bool ok = setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes)) == 0 &&
            setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &receive_buffer, sizeof(receive_buffer)) == 0;
  if (ok && a.ai_family == AF_INET6) {  // "::" takes IPv4 as well, as cpp-httplib did
    ok = setsockopt(fd, IPPROTO_IPV6, IPV6_V6ONLY, &no, sizeof(no)) == 0;
  }
  if (ok && bind(fd, a.ai_addr, a.ai_addrlen) == 0 &&
      listen(fd, metrics_port::kListenBacklog) == 0) {
    return fd;
  }
  const int saved = errno;
  close(fd);
  errno = saved;
  return -1;
}

int BoundPort(int fd) {
  sockaddr_storage address{};
  socklen_t length = sizeof(address);
  if (getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length) != 0) return -1;
  if (address.ss_family == AF_INET6) {
    return ntohs(reinterpret_cast<const sockaddr_in6*>(&address)->sin6_port);
  }
  return ntohs(reinterpret_cast<const sockaddr_in*>(&address)->sin_port);
}

}  // namespace

Result<ListenSocket> OpenListenSocket(const std::string& listen) {
  auto address = ParseListen(listen);
  if (!address.ok()) return address.status();
  const auto refused = [&](const std::string& why) {
    return Unavailable(fmt::format(
        "--metrics-listen {}: cannot listen on port {} of '{}' (taken by another process, or "
        "not an address of this host): {}",
        listen, address->port, address->host, why));
  };
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
  addrinfo* found = nullptr;
  const std::string service = std::to_string(address->port);
  if (const int rc = getaddrinfo(address->host.c_str(), service.c_str(), &hints, &found); rc != 0) {
    return refused(gai_strerror(rc));
  }
  ListenSocket out;
  int error = 0;
  for (const addrinfo* a = found; a != nullptr && out.fd < 0; a = a->ai_next) {
    out.fd = BindAndListen(*a);
    if (out.fd < 0) error = errno;
  }
  freeaddrinfo(found);
  if (out.fd < 0) return refused(std::strerror(error));
  out.port = BoundPort(out.fd);
  if (out.port <= 0) {
    const int saved = errno;
    close(out.fd);
    return refused(std::strerror(saved));
  }
  return out;
}

}  // namespace skinserve::server
