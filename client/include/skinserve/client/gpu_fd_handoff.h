// The client's side of GPU regions' fd handoff (docs/serving/gpu-regions.md): sends an
// exported GPU buffer's opaque file descriptor to the server's --gpu-fd-socket with
// SCM_RIGHTS and returns the one-time token to name in RegisterGpuRegionRequest.fd_token.
// The token is good only for gRPC calls from this same process, once, for 30 s.
#pragma once

#include <string>

#include "skinserve/model/status.h"

namespace skinserve::client {

// The fd stays the caller's (the server receives a duplicate). UNAVAILABLE when the socket
// cannot be reached; the server's refusal ("ERR ...") as FAILED_PRECONDITION, or
// RESOURCE_EXHAUSTED when it holds too many fds waiting already.
Result<std::string> HandOverGpuFd(const std::string& socket_path, int fd);

}  // namespace skinserve::client
