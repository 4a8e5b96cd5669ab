// The bounds of the metrics port (issue 42): everything a client of that port can make the
// server hold or spend. Constants, not options: they bound an attack, not a workload (one
// Prometheus scrape is one small GET at a time), and docs/operations.md#metrics states them.
// Together: at most kMaxConnections x (kMaxRequestHeadBytes + one rendered exposition) of
// the server's memory, one thread, and a connection's life of at most
// kRequestTimeout + kAnswerTimeout + kLinger.
#pragma once

#include <chrono>
#include <cstddef>

namespace skinserve::server::metrics_port {

// Connections served at once; one more is accepted and closed at once (no queue beyond
// the kernel's listen backlog, kListenBacklog).
inline constexpr std::size_t kMaxConnections = 16;
inline constexpr int kListenBacklog = 64;
// The request line and headers together; a head that reaches it unfinished gets 431.
inline constexpr std::size_t kMaxRequestHeadBytes = 8192;
// From accept to the head's empty line, however the bytes trickle in (slow senders): 408.
inline constexpr std::chrono::seconds kRequestTimeout{5};
// For the client to take the answer; a client that reads nothing is closed after it.
inline constexpr std::chrono::seconds kAnswerTimeout{5};
// After the answer, what the client still sends (a body nobody reads) is read and
// dropped, up to kMaxDiscardBytes or kLinger, so that closing does not reset the
// connection before the client has read the answer; then the connection is closed.
inline constexpr std::size_t kMaxDiscardBytes = 64 * 1024;
inline constexpr std::chrono::seconds kLinger{1};
// The kernel's receive buffer of each connection (SO_RCVBUF; Linux doubles it): what a
// sender can park in kernel memory before the server reads it.
inline constexpr int kReceiveBufferBytes = 16 * 1024;
// The serving thread's nice value: under a flood it yields the cores to gRPC and the
// compute threads.
inline constexpr int kThreadNice = 10;

}  // namespace skinserve::server::metrics_port
