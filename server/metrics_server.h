// MetricsServer: GET /metrics in Prometheus' text format on an HTTP port of its own,
// served by cpp-httplib (Debian's libcpp-httplib-dev) on its own threads, so a scrape
// never waits for gRPC work and gRPC work never waits for a scrape.
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <string>
#include <thread>

#include "skinserve/model/status.h"

namespace httplib {
class Server;
}

namespace skinserve::server {

class MetricsServer {
 public:
  using Render = std::function<std::string()>;
  // Binds `listen` ("host:port", "[v6]:port"; port 0 picks a free one) before returning,
  // so a taken port is an error here, naming the address. `render` runs on the HTTP
  // threads, once per scrape.
  static Result<std::unique_ptr<MetricsServer>> Start(const std::string& listen, Render render);
  ~MetricsServer();  // Stop()

  int port() const { return port_; }
  // Stops listening and waits for scrapes in progress to be answered. Idempotent.
  void Stop();

 private:
  MetricsServer() = default;
  std::unique_ptr<httplib::Server> http_;
  std::thread thread_;
  int port_ = 0;
  std::atomic<bool> loop_done_{false};
};

}  // namespace skinserve::server
