// The metrics port's listening socket: "host:port" parsed, resolved and bound before the
// server reports it started, so a taken port or a foreign address stops start-up with an
// error naming it.
#pragma once

#include <string>

#include "skinserve/model/status.h"

namespace skinserve::server {

struct ListenSocket {
  int fd = -1;   // non-blocking, close-on-exec, listening
  int port = 0;  // the bound port (the kernel's choice when asked for 0)
};

// `listen`: "host:port" or "[v6]:port"; port 0 picks a free one. SO_REUSEADDR without
// SO_REUSEPORT (with it a second process could bind a port already taken), the receive
// buffer and backlog of metrics_port_limits.h.
Result<ListenSocket> OpenListenSocket(const std::string& listen);

}  // namespace skinserve::server
