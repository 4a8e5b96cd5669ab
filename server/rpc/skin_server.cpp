#include "rpc/skin_server.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/health_check_service_interface.h>
#include <grpcpp/impl/server_builder_option.h>
#include <grpcpp/resource_quota.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <thread>

#include "observability/log_format.h"
#include "observability/metrics_frames.h"
#include "observability/metrics_text.h"
#include "observability/process_metrics.h"
#include "rpc/unix_listener.h"
#include "security/authz_policy_file.h"
#include "security/server_tls.h"
#include "shm/sigbus_guard.h"

namespace skinserve::server {
namespace {

// How long drained streams' final statuses get to reach their clients before gRPC's
// shutdown may close the connections (see Shutdown). Loopback needs well under 1 ms.
constexpr std::chrono::milliseconds kStatusLinger{100};

// Clients may send keepalive pings this often on a connection the server sends nothing on
// (gRPC's default, 5 minutes, answers a client pinging every 10 s with GOAWAY
// "too_many_pings" after two pings). The client library pings every 10 s.
constexpr int kMinClientPingIntervalMs = 1000;

// --reflection=false: gRPC registers reflection as a plugin of every ServerBuilder of the
// process once InitProtoReflectionServerBuilderPlugin ran; this option takes it out again
// for this server alone.
class WithoutReflection : public grpc::ServerBuilderOption {
 public:
  void UpdateArguments(grpc::ChannelArguments*) override {}
  void UpdatePlugins(std::vector<std::unique_ptr<grpc::ServerBuilderPlugin>>* plugins) override {
    std::erase_if(*plugins,
                  [](const auto& plugin) { return plugin->name() == "proto_server_reflection"; });
  }
};

// Threads gRPC may start for synchronous methods: reflection's (the service's own methods
// are callbacks, on gRPC's shared threads), one per open reflection stream otherwise.
// Beyond it, a new reflection call is refused RESOURCE_EXHAUSTED.
constexpr int kGrpcMaxThreads = 32;

int Milliseconds(double seconds) { return static_cast<int>(std::min(seconds * 1000, 2.0e9)); }

// What gRPC 1.51 offers against many, idle or silent connections; it cannot cap their
// number (GRPC_ARG_MAX_ALLOWED_INCOMING_CONNECTIONS came in 2024). docs/security.md says
// what this bounds and what not.
void AddConnectionLimits(const ServerOptions& options, grpc::ServerBuilder* builder) {
  builder->AddChannelArgument(GRPC_ARG_SERVER_HANDSHAKE_TIMEOUT_MS,
                              Milliseconds(options.handshake_timeout_seconds));
  if (options.connection_idle_seconds > 0) {
    builder->AddChannelArgument(GRPC_ARG_MAX_CONNECTION_IDLE_MS,
                                Milliseconds(options.connection_idle_seconds));
  }
  grpc::ResourceQuota quota("skinserve");
  quota.Resize(options.GrpcMemoryBytes()).SetMaxThreads(kGrpcMaxThreads);
  builder->SetResourceQuota(quota);
}

std::string DescribeSecurity(const ServerOptions& options) {
  if (options.tls_cert.empty()) return "plaintext";
  return fmt::format("{} (files re-read every {} s)",
                     options.tls_client_ca.empty() ? "TLS" : "mutual TLS",
                     options.tls_refresh_seconds);
}

// The channel's settings: reflection or not, keepalive, the connection limits, the largest
// message and the connections' age.
void ConfigureBuilder(const ServerOptions& options, grpc::ServerBuilder& builder) {
  if (!options.reflection) builder.SetOption(std::make_unique<WithoutReflection>());
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIME_MS, Milliseconds(options.keepalive_seconds));
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIMEOUT_MS,
                             Milliseconds(options.keepalive_timeout_seconds));
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS,
                             kMinClientPingIntervalMs);
  AddConnectionLimits(options, &builder);
  // A tick may exceed gRPC's default 4 MiB message (its scan refuses what is over
  // --max-tick-bytes, and a plain frame over 4 MiB, before the parse).
  builder.SetMaxReceiveMessageSize(
      static_cast<int>(std::max<uint64_t>(options.max_tick_bytes, kMaxFrameRequestBytes)));
  if (options.max_connection_age_seconds > 0) {
    builder.AddChannelArgument(GRPC_ARG_MAX_CONNECTION_AGE_MS,
                               Milliseconds(options.max_connection_age_seconds));
    builder.AddChannelArgument(GRPC_ARG_MAX_CONNECTION_AGE_GRACE_MS,
                               Milliseconds(options.max_connection_age_grace_seconds));
  }
}

void LogListening(const ServerOptions& options, int port) {
  spdlog::info(
      "listening on {} (port {}; TCP {}{}, unix: plaintext; shared-memory regions {}; "
      "reflection {}); building backends",
      fmt::join(options.listen, ", "), port, DescribeSecurity(options),
      options.authz_policy.empty()
          ? ""
          : fmt::format(", authorization policy {} re-read every {} s", options.authz_policy,
                        options.authz_refresh_seconds),
      options.shm_dir.empty() ? "off"
      : options.shm_over_tcp  ? "on unix: and mutual-TLS TCP"
                              : "on unix: only",
      options.reflection ? "on" : "off");
}

}  // namespace

void SkinServer::SetReady(bool ready) {
  grpc::HealthCheckServiceInterface* health = server_->GetHealthCheckService();
  health->SetServingStatus("", ready);
  health->SetServingStatus(v1::Skinning::service_full_name(), ready);
}

Status SkinServer::ListenOn(const ServerOptions& options,
                            const std::shared_ptr<grpc::ServerCredentials>& tcp_credentials,
                            grpc::ServerBuilder& builder) {
  // unix: addresses are accepted here (UnixListener: the peer's credentials), the others
  // by gRPC.
  std::vector<int> ports(options.listen.size(), 0);
  for (std::size_t i = 0; i < options.listen.size(); ++i) {
    if (options.listen[i].rfind("unix:", 0) == 0) {
      auto listener = UnixListener::Listen(options.listen[i], &unix_peers_);
      if (!listener.ok()) return listener.status();
      unix_listeners_.push_back(std::move(listener).value());
    } else {
      builder.AddListeningPort(options.listen[i], tcp_credentials, &ports[i]);
    }
  }
  builder.AddChannelArgument(GRPC_ARG_MAX_CONCURRENT_STREAMS, options.max_streams_per_connection);
  builder.RegisterService(service_.get());
  if (gpu_regions_) builder.RegisterService(gpu_regions_->service.get());
  server_ = builder.BuildAndStart();
  for (std::size_t i = 0; i < options.listen.size(); ++i) {
    if (options.listen[i].rfind("unix:", 0) == 0) continue;
    if (!server_ || ports[i] == 0) {
      return Unavailable(fmt::format("cannot listen on {}", options.listen[i]));
    }
    // The first TCP address's port is the one --port-file reports.
    if (port_ == 0) port_ = ports[i];
  }
  if (!server_) {
    return Unavailable(fmt::format("cannot serve on {}", fmt::join(options.listen, ", ")));
  }
  for (auto& listener : unix_listeners_) listener->Start(server_.get());
  return Status::Ok();
}

Result<std::shared_ptr<grpc::ServerCredentials>> SkinServer::CreateService(
    const ServerOptions& options) {
  if (!options.shm_dir.empty()) {
    auto regions = RegionRegistry::Create(options.ToRegionLimits());
    if (!regions.ok()) return regions.status();
    regions_ = std::move(regions).value();
  }
  auto tcp_credentials = MakeTcpCredentials(options);
  if (!tcp_credentials.ok()) return tcp_credentials.status();
  if (!options.authz_policy.empty()) {
    auto policy = PolicyFile::Load(
        options.authz_policy,
        std::chrono::milliseconds(static_cast<int64_t>(options.authz_refresh_seconds * 1000)));
    if (!policy.ok()) return policy.status();
    policy_ = std::move(policy).value();
  }
  service_ = std::make_unique<SkinningService>(
      options.default_backend, options.stream_window, options.ToStreamLimits(),
      options.InflightBudgetBytes(), options.ToUploadLimits(), regions_.get(), policy_.get(),
      RegionAccessPolicy{.unix_peers = &unix_peers_, .over_tcp = options.shm_over_tcp});
  service_->SetRequestLimits(options.ToRequestLimits());
  auto gpu_regions = GpuRegionsOnServer::Start(options, &unix_peers_, policy_.get());
  if (!gpu_regions.ok()) return gpu_regions.status();
  gpu_regions_ = std::move(gpu_regions).value();
  if (gpu_regions_) service_->SetGpuRegions(gpu_regions_->registry.get());
  return tcp_credentials;
}

Status SkinServer::StartEngine(const ServerOptions& options) {
  spdlog::info("{}", options.DescribeSizing());
  EngineOptions engine_options = options.ToEngineOptions();
  // A frame into a region relies on the SIGBUS guard; a backend preparing a mesh may have
  // compiled kernels, and the compiler may have replaced the handler (sigbus_guard.h).
  engine_options.after_prepare = [] { SigbusGuard::Install(); };
  auto engine = Engine::Create(engine_options);
  if (!engine.ok()) return engine.status();
  engine_ = std::move(engine).value();
  const auto backends = engine_->Backends();
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
  service_->SetEngine(engine_.get());
  if (gpu_regions_) gpu_regions_->service->SetEngine(engine_.get());
  if (FrameMetrics* frames = FrameMetrics::Installed()) {
    std::vector<std::string> ids;
    for (const BackendInfo& b : backends) ids.push_back(b.id);
    frames->SetBackends(ids);
  }
  return Status::Ok();
}

Status SkinServer::StartFrameSocket(const ServerOptions& options) {
  if (options.frame_socket.empty()) return Status::Ok();
  auto socket = FrameSocket::Listen({.path = options.frame_socket,
                                     .max_connections = options.frame_socket_max_connections,
                                     .idle_seconds = options.stream_idle_seconds},
                                    [service = service_.get()](const UnixPeerCredentials& peer) {
                                      return service->FrameSocketAccessFor(peer);
                                    });
  if (!socket.ok()) return socket.status();
  frame_socket_ = std::move(socket).value();
  spdlog::info("frame socket on {} (at most {} connections)", options.frame_socket,
               options.frame_socket_max_connections);
  return Status::Ok();
}

Result<std::unique_ptr<SkinServer>> SkinServer::Start(const ServerOptions& options) {
  spdlog::set_level(spdlog::level::from_str(options.log_level));
  SetLogFormat(options.log_format);
  const MemoryEnvelope envelope = options.Envelope();
  if (Status s = envelope.Check(); !s.ok()) return s;
  spdlog::info("memory envelope:\n{}", envelope.Describe());
  std::unique_ptr<SkinServer> server(new SkinServer());
  auto tcp_credentials = server->CreateService(options);
  if (!tcp_credentials.ok()) return tcp_credentials.status();
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  ConfigureBuilder(options, builder);
  if (options.listen.empty()) return InvalidArgument("--listen names no address");
  if (Status s = server->ListenOn(options, *tcp_credentials, builder); !s.ok()) return s;
  // Readiness ("" and the service's name) waits for the engine; liveness answers SERVING
  // from now until the process stops, draining included
  // (docs/deployment/kubernetes.md#probes).
  server->SetReady(false);
  server->server_->GetHealthCheckService()->SetServingStatus(kLivenessService, true);
  LogListening(options, server->port_);
  // The per-frame histograms feed GetServerStats as well as /metrics: always on.
  FrameMetrics::Enable();
  if (!options.metrics_listen.empty()) {
    auto metrics = MetricsServer::Start(options.metrics_listen,
                                        [s = server.get()] { return s->RenderMetrics(); });
    if (!metrics.ok()) return metrics.status();
    server->metrics_ = std::move(metrics).value();
    spdlog::info("metrics on http://{}/metrics (port {})", options.metrics_listen,
                 server->metrics_->port());
  }
  if (Status s = server->StartEngine(options); !s.ok()) return s;
  if (Status s = server->StartFrameSocket(options); !s.ok()) return s;
  server->SetReady(true);
  server->service_->SetServing(true);
  spdlog::info("serving");
  return server;
}

SkinServer::~SkinServer() { Shutdown(std::chrono::milliseconds(0)); }

void SkinServer::Shutdown(std::chrono::milliseconds grace) {
  std::call_once(shutdown_once_, [&] {
    if (service_) service_->SetServing(false);
    if (server_) {
      SetReady(false);
      spdlog::info("draining: up to {} ms for in-flight calls", grace.count());
      const auto deadline = std::chrono::steady_clock::now() + grace;
      const bool had_streams = service_->OpenStreamCount() > 0;
      service_->Drain();  // streams end UNAVAILABLE once their frames are answered
      // Frame-socket connections likewise, each once the request it serves is answered.
      if (frame_socket_) frame_socket_->Stop();
      // The streams end before gRPC's shutdown begins. Once gRPC has sent GOAWAY it closes
      // a connection the moment its last stream ends; bytes the client sent meanwhile (its
      // window updates) are then unread, the close becomes a reset, and the reset discards
      // the stream's final status in the client's socket ("Broken pipe" instead of the
      // drain's message). The linger lets the clients read that status first.
      if (service_->WaitUntilStreamsEnded(deadline) && had_streams) {
        std::this_thread::sleep_until(
            std::min(deadline, std::chrono::steady_clock::now() + kStatusLinger));
      }
      const auto left = std::max(deadline - std::chrono::steady_clock::now(),
                                 std::chrono::steady_clock::duration::zero());
      // gRPC stops accepting on its addresses now: so do the Unix sockets, before.
      for (auto& listener : unix_listeners_) listener->Stop();
      server_->Shutdown(std::chrono::system_clock::now() + left);
    }
    if (engine_) engine_->Shutdown();  // the frames still queued finish; nobody waits
    if (server_) server_->Wait();
    if (metrics_) metrics_->Stop();  // scrapes are answered until every call is done
    spdlog::info("stopped");
  });
}

// The process series first: RenderPrometheusText ends with the line that marks a whole scrape.
std::string SkinServer::RenderMetrics() const {
  return RenderProcessMetrics() + RenderPrometheusText(service_->Snapshot());
}

void SkinServer::Wait() {
  if (server_) server_->Wait();
}

}  // namespace skinserve::server
