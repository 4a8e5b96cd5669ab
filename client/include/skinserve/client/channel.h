// Channels to skinserve: one address, or several behind gRPC's client-side round_robin
// (e.g. "ipv4:127.0.0.1:50051,127.0.0.1:50052", or a DNS name with many A records).
#pragma once

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <memory>
#include <string>

#include "skinserve/model/status.h"

namespace skinserve::client {

inline constexpr char kDefaultTarget[] = "127.0.0.1:50051";

// The files a client presents and trusts (PEM). No CA: plaintext. A certificate and key:
// mutual TLS, for servers started with --tls-client-ca.
struct TlsFiles {
  std::string ca;           // the CA that signed the server's certificate
  std::string cert, key;    // this client's certificate chain and key (both, or neither)
  std::string server_name;  // the name the server's certificate must carry, when the
                            // target's host is not it (an IP address, a unix: socket)
  bool enabled() const { return !ca.empty() || !cert.empty() || !key.empty(); }
};

// How a channel reaches its server. Keepalive: with calls open, a ping every
// `keepalive_time`; a ping unanswered for `keepalive_timeout` closes the connection and fails
// its calls UNAVAILABLE, so a server that vanished without a FIN (a dropped link, a node
// gone) is given up on within time + timeout (15 s by default) instead of TCP's minutes.
struct ChannelOptions {
  std::shared_ptr<grpc::ChannelCredentials> credentials;  // null: plaintext (insecure)
  std::string server_name;  // TLS: overrides the name checked in the server's certificate
  std::chrono::milliseconds keepalive_time{10'000};  // 0: no keepalive pings
  std::chrono::milliseconds keepalive_timeout{5'000};
};

// TLS credentials from `files` (read now; a missing or unreadable file is an error naming
// the option, --tls-ca, --tls-cert or --tls-key); plaintext when !files.enabled().
Result<ChannelOptions> ChannelOptionsFromFiles(const TlsFiles& files);

// Balances per call (and per stream) across every address the target resolves to.
// Channels to the same target share their TCP connections (gRPC's subchannel pool) unless
// their `connection` differs. Heavy streams want a pool of connections, as separate
// clients would have: a server takes only so many streams on one connection at once
// (HTTP/2 MAX_CONCURRENT_STREAMS; later calls wait at the client) and gRPC works one
// connection on one thread at a time.
std::shared_ptr<grpc::Channel> MakeChannel(const std::string& target, const ChannelOptions& options,
                                           int connection = 0);
// Plaintext, default keepalive.
std::shared_ptr<grpc::Channel> MakeChannel(const std::string& target, int connection = 0);

// For a call that failed before reaching the server, what TLS setting likely caused it
// (gRPC's own reasons, e.g. "Socket closed", do not say); empty when nothing fits. Names the
// command-line options (--tls-ca, ...).
std::string ConnectionHint(const Status& status);

// Asks the standard health service about `service` ("": the whole server, which is what
// readiness means here; skinserve's "liveness" answers SERVING while the process serves at
// all); OK when it answers SERVING, else why not.
Status CheckHealth(grpc::Channel& channel, std::chrono::milliseconds timeout,
                   const std::string& service = "");
// Polls CheckHealth until SERVING or `timeout`.
Status WaitUntilServing(grpc::Channel& channel, std::chrono::milliseconds timeout);

}  // namespace skinserve::client
