#include "skin_server.h"

#include <fmt/format.h>
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/health_check_service_interface.h>
#include <spdlog/spdlog.h>

#include <algorithm>

namespace skinserve::server {

Result<std::unique_ptr<SkinServer>> SkinServer::Start(const ServerOptions& options) {
  spdlog::set_level(spdlog::level::from_str(options.log_level));
  std::unique_ptr<SkinServer> server(new SkinServer());
  server->service_ = std::make_unique<SkinningService>(options.default_backend,
                                                       options.stream_window, options.max_streams);
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  builder.AddListeningPort(options.listen, grpc::InsecureServerCredentials(), &server->port_);
  builder.AddChannelArgument(GRPC_ARG_MAX_CONCURRENT_STREAMS, options.max_streams_per_connection);
  builder.RegisterService(server->service_.get());
  server->server_ = builder.BuildAndStart();
  if (!server->server_ || server->port_ == 0) {
    return Unavailable(fmt::format("cannot listen on {}", options.listen));
  }
  grpc::HealthCheckServiceInterface* health = server->server_->GetHealthCheckService();
  health->SetServingStatus(false);
  spdlog::info("listening on {} (port {}); building backends", options.listen, server->port_);

  auto engine = Engine::Create(options.ToEngineOptions());
  if (!engine.ok()) return engine.status();
  server->engine_ = std::move(engine).value();
  const auto backends = server->engine_->Backends();
  const bool default_ok = std::any_of(backends.begin(), backends.end(), [&](const auto& b) {
    return b.id == options.default_backend && b.available;
  });
  if (!default_ok) {
    return InvalidArgument(fmt::format(
        "--default-backend '{}' is not an enabled, available backend", options.default_backend));
  }
  for (const BackendInfo& b : backends) {
    if (b.available) {
      spdlog::info("backend {:<16} {} [{}; {} threads]", b.id, b.description, b.device, b.threads);
    } else {
      spdlog::warn("backend {:<16} unavailable: {}", b.id, b.unavailable_reason);
    }
  }
  server->service_->SetEngine(server->engine_.get());
  health->SetServingStatus(true);
  spdlog::info("serving");
  return server;
}

SkinServer::~SkinServer() { Shutdown(std::chrono::milliseconds(0)); }

void SkinServer::Shutdown(std::chrono::milliseconds grace) {
  std::call_once(shutdown_once_, [&] {
    if (server_) {
      server_->GetHealthCheckService()->SetServingStatus(false);
      service_->Drain();  // streams end UNAVAILABLE once their frames are answered
      spdlog::info("draining: up to {} ms for in-flight calls", grace.count());
      server_->Shutdown(std::chrono::system_clock::now() + grace);
    }
    if (engine_) engine_->Shutdown();  // the frames still queued finish; nobody waits
    if (server_) server_->Wait();
    spdlog::info("stopped");
  });
}

void SkinServer::Wait() {
  if (server_) server_->Wait();
}

}  // namespace skinserve::server
