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

// Balances per call (and per stream) across every address the target resolves to.
// Channels to the same target share their TCP connections (gRPC's subchannel pool) unless
// their `connection` differs. Heavy streams want a pool of connections, as separate
// clients would have: a server takes only so many streams on one connection at once
// (HTTP/2 MAX_CONCURRENT_STREAMS; later calls wait at the client) and gRPC works one
// connection on one thread at a time.
std::shared_ptr<grpc::Channel> MakeChannel(const std::string& target, int connection = 0);

// Asks the standard health service; OK when it answers SERVING, else why not.
Status CheckHealth(grpc::Channel& channel, std::chrono::milliseconds timeout);
// Polls CheckHealth until SERVING or `timeout`.
Status WaitUntilServing(grpc::Channel& channel, std::chrono::milliseconds timeout);

}  // namespace skinserve::client
