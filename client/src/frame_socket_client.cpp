#include "skinserve/client/frame_socket_client.h"

#include <fmt/format.h>
#include <grpc/slice.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "skinserve/wire/conversions.h"
#include "skinserve/wire/frame_socket_protocol.h"

namespace skinserve::client {
namespace {

constexpr std::size_t kHeaderBytes = wire::kFrameSocketHeaderBytes;

bool SendAll(int fd, const char* data, std::size_t bytes) {
  while (bytes > 0) {
    const ssize_t sent = send(fd, data, bytes, MSG_NOSIGNAL);
    if (sent < 0 && errno == EINTR) continue;
    if (sent <= 0) return false;
    data += sent;
    bytes -= static_cast<std::size_t>(sent);
  }
  return true;
}

}  // namespace

Result<std::unique_ptr<FrameSocketClient>> FrameSocketClient::Connect(const std::string& path) {
  sockaddr_un addr = {};
  addr.sun_family = AF_UNIX;
  if (path.empty() || path.size() >= sizeof(addr.sun_path)) {
    return InvalidArgument(fmt::format("frame socket path '{}': must be 1 to {} bytes", path,
                                       sizeof(addr.sun_path) - 1));
  }
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  const int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return Unavailable(fmt::format("socket: {}", std::strerror(errno)));
  if (connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0) {
    const std::string why = std::strerror(errno);
    close(fd);
    return Unavailable(fmt::format("cannot connect to the frame socket {}: {}", path, why));
  }
  // A greeting that cannot be sent is no error here: a server that refuses the connection
  // (over --frame-socket-max-connections, the policy) may have answered and closed it
  // already, and Read then gives its reason.
  (void)SendAll(fd, wire::kFrameSocketHello.data(), wire::kFrameSocketHello.size());
  return std::unique_ptr<FrameSocketClient>(new FrameSocketClient(fd));
}

FrameSocketClient::~FrameSocketClient() { close(fd_); }

bool FrameSocketClient::Write(const v1::SkinRequest& request) {
  const std::size_t size = request.ByteSizeLong();
  if (size > wire::kFrameSocketSizeMask) return false;
  out_.resize(kHeaderBytes + size);
  wire::WriteFrameSocketHeader(static_cast<uint32_t>(size),
                               reinterpret_cast<unsigned char*>(out_.data()));
  request.SerializeWithCachedSizesToArray(reinterpret_cast<uint8_t*>(out_.data() + kHeaderBytes));
  return SendAll(fd_, out_.data(), out_.size());
}

void FrameSocketClient::WritesDone() { shutdown(fd_, SHUT_WR); }

void FrameSocketClient::Cancel() {
  cancelled_.store(true);
  shutdown(fd_, SHUT_RDWR);
}

bool FrameSocketClient::ReadExactly(void* into, std::size_t bytes) {
  auto* at = static_cast<char*>(into);
  while (bytes > 0) {
    // Waiting in poll, not in recv: recv's wait also wakes each time the server reads a
    // request (the kernel wakes a Unix socket's sleepers when its sent bytes are consumed),
    // and that wake-up costs the server an interrupt to this thread's core each frame.
    const ssize_t got = recv(fd_, at, bytes, MSG_DONTWAIT);
    if (got < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      pollfd readable = {fd_, POLLIN, 0};
      if (poll(&readable, 1, -1) >= 0 || errno == EINTR) continue;
    }
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) {
      end_ = cancelled_.load() ? Status(StatusCode::kCancelled, "cancelled")
             : got == 0
                 ? Unavailable("the frame socket closed without saying why")
                 : Unavailable(fmt::format("the frame socket failed: {}", std::strerror(errno)));
      return false;
    }
    at += got;
    bytes -= static_cast<std::size_t>(got);
  }
  return true;
}

bool FrameSocketClient::Read(grpc::ByteBuffer* part) {
  unsigned char header[kHeaderBytes];
  if (!ReadExactly(header, kHeaderBytes)) return false;
  const uint32_t value = wire::ReadFrameSocketHeader(header);
  const std::size_t size = value & wire::kFrameSocketSizeMask;
  // Read straight into a slice the ByteBuffer then owns: no copy of the vertices.
  grpc_slice slice = grpc_slice_malloc(size);
  if (!ReadExactly(GRPC_SLICE_START_PTR(slice), size)) {
    grpc_slice_unref(slice);
    return false;
  }
  grpc::Slice owned(slice, grpc::Slice::STEAL_REF);
  if ((value & wire::kFrameSocketEndBit) == 0) {
    *part = grpc::ByteBuffer(&owned, 1);
    return true;
  }
  v1::SkinResponse end;
  if (!end.ParseFromArray(owned.begin(), static_cast<int>(owned.size()))) {
    end_ = Internal("the frame socket's last message is not a SkinResponse");
  } else {
    end_ = wire::FromGrpc(
        grpc::Status(static_cast<grpc::StatusCode>(end.error().code()), end.error().message()));
  }
  return false;
}

}  // namespace skinserve::client
