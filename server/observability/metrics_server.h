// MetricsServer: GET /metrics in Prometheus' text format on an HTTP port of its own, served
// by one thread of its own, so a scrape never waits for gRPC work and gRPC work never waits
// for a scrape.
//
// Why not cpp-httplib any more (issue 42: two connections POSTing to /metrics took the
// server from 840 MB to 1.4 GB): Debian's libcpp-httplib 0.11 is a compiled library, so its
// CPPHTTPLIB_* limits are fixed at no payload limit and a per-read (not per-request)
// timeout; it reads a header line whole before checking its length; and its TaskQueue
// cannot refuse a connection (a dropped task leaks the socket), so accepted connections
// queue without bound behind its threads. Closing each of those holes around it would
// leave more code than this: a GET-only HTTP/1.1 responder on poll(), one request per
// connection, every byte a client can make it hold bounded by metrics_port_limits.h.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <thread>

#include "observability/metrics_port_limits.h"
#include "skinserve/model/status.h"

namespace skinserve::server {

class MetricsServer {
 public:
  using Render = std::function<std::string()>;
  // Binds `listen` ("host:port", "[v6]:port"; port 0 picks a free one) before returning,
  // so a taken port is an error here, naming the address. `render` runs on the metrics
  // thread, once per scrape.
  static Result<std::unique_ptr<MetricsServer>> Start(const std::string& listen, Render render);
  ~MetricsServer();  // Stop()
  MetricsServer(const MetricsServer&) = delete;
  MetricsServer& operator=(const MetricsServer&) = delete;

  int port() const { return port_; }
  // Stops listening, closes connections still sending their request and waits for answers
  // being written (at most metrics_port::kAnswerTimeout + kLinger). Idempotent.
  void Stop();

 private:
  class Loop;
  MetricsServer() = default;
  std::unique_ptr<Loop> loop_;
  std::thread thread_;
  int port_ = 0;
};

}  // namespace skinserve::server
