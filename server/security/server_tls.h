// The credentials of the gRPC server's TCP addresses: TLS from certificate files that gRPC
// re-reads on a timer (its file-watcher certificate provider), so that a rotated secret
// reaches new connections without a restart; mutual TLS when a client CA is given.
// Without --tls-cert: plaintext, as before.
#pragma once

#include <grpcpp/security/server_credentials.h>

#include <memory>

#include "options/server_options.h"

namespace skinserve::server {

// Checks that the files exist and hold PEM blocks (so a wrong path is a start-up error
// naming the flag, not a handshake failure per connection), then makes the credentials.
Result<std::shared_ptr<grpc::ServerCredentials>> MakeTcpCredentials(const ServerOptions& options);

// Unix sockets (UnixListener) serve same-host clients, guarded by their folder's
// permissions: plaintext, whatever the TCP credentials are.

}  // namespace skinserve::server
