// The connection flags every command-line client shares (skinserve-cli, skinserve-load):
// TLS files, the server name and keepalive, each with its environment variable, and the
// channel options they make. Deadlines stay with each tool: they mean different things there.
#pragma once

#include <CLI/CLI.hpp>

#include "skinserve/client/channel.h"
#include "skinserve/model/status.h"

namespace skinserve::client {

struct ConnectionFlags {
  TlsFiles tls;
  double keepalive_seconds = 10;
  double keepalive_timeout_seconds = 5;

  // TLS from the files (read now: an unreadable one is an error naming its flag) and the
  // keepalive.
  Result<ChannelOptions> ToChannelOptions() const;
};

// --tls-ca, --tls-cert, --tls-key, --tls-server-name, --keepalive-seconds and
// --keepalive-timeout-seconds on `app`.
void AddConnectionFlags(CLI::App& app, ConnectionFlags& flags);

// Seconds from a flag as milliseconds (sub-millisecond parts dropped).
std::chrono::milliseconds FlagMilliseconds(double seconds);

}  // namespace skinserve::client
