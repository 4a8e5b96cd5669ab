#include "metrics_server.h"

#include <fmt/format.h>
#include <httplib.h>
#include <sys/socket.h>

#include <charconv>

namespace skinserve::server {

namespace {

struct HostPort {
  std::string host;
  int port = -1;
};

Result<HostPort> ParseListen(const std::string& listen) {
  const std::size_t colon = listen.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == listen.size()) {
    return InvalidArgument(fmt::format("--metrics-listen '{}': expected host:port", listen));
  }
  HostPort out;
  out.host = listen.substr(0, colon);
  if (out.host.size() >= 2 && out.host.front() == '[' && out.host.back() == ']') {
    out.host = out.host.substr(1, out.host.size() - 2);
  }
  const char* begin = listen.data() + colon + 1;
  const char* end = listen.data() + listen.size();
  const auto [ptr, ec] = std::from_chars(begin, end, out.port);
  if (ec != std::errc() || ptr != end || out.port < 0 || out.port > 65535) {
    return InvalidArgument(
        fmt::format("--metrics-listen '{}': the port must be a number 0..65535", listen));
  }
  return out;
}

}  // namespace

Result<std::unique_ptr<MetricsServer>> MetricsServer::Start(const std::string& listen,
                                                            Render render) {
  auto address = ParseListen(listen);
  if (!address.ok()) return address.status();
  std::unique_ptr<MetricsServer> server(new MetricsServer());
  server->http_ = std::make_unique<httplib::Server>();
  httplib::Server& http = *server->http_;
  // cpp-httplib sets SO_REUSEPORT by default, which lets a second process bind a port
  // already taken (gRPC sets it too): SO_REUSEADDR alone, so a taken port fails here.
  http.set_socket_options([](socket_t sock) {
    int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
  });
  http.Get("/metrics",
           [render = std::move(render)](const httplib::Request&, httplib::Response& response) {
             response.set_content(render(), "text/plain; version=0.0.4; charset=utf-8");
           });
  if (address->port == 0) {
    server->port_ = http.bind_to_any_port(address->host);
  } else if (http.bind_to_port(address->host, address->port)) {
    server->port_ = address->port;
  }
  if (server->port_ <= 0) {
    return Unavailable(fmt::format(
        "--metrics-listen {}: cannot listen on port {} of '{}' (taken by another process, or "
        "not an address of this host)",
        listen, address->port, address->host));
  }
  MetricsServer* self = server.get();
  server->thread_ = std::thread([self] {
    self->http_->listen_after_bind();
    self->loop_done_.store(true);
  });
  // stop() before the loop runs would be lost (and Stop() would wait forever).
  while (!http.is_running() && !server->loop_done_.load()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return server;
}

MetricsServer::~MetricsServer() { Stop(); }

void MetricsServer::Stop() {
  if (!thread_.joinable()) return;
  http_->stop();
  thread_.join();  // listen_after_bind returns once its worker threads are joined
}

}  // namespace skinserve::server
