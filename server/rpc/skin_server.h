// SkinServer: the gRPC server around an Engine. It listens at once with health
// NOT_SERVING, builds the engine (and with it the OpenCL program), then reports SERVING.
// Used by main and, in-process, by the integration tests.
#pragma once

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <vector>

#include "gpu/gpu_regions_on_server.h"
#include "observability/metrics_server.h"
#include "options/server_options.h"
#include "rpc/skinning_service.h"
#include "rpc/unix_listener.h"
#include "security/authz_policy_file.h"
#include "socket/frame_socket.h"

namespace skinserve::server {

// The health service's name for liveness: SERVING from the moment the server listens until
// it stops, whether or not it is ready (the names "" and "skinserve.v1.Skinning" say that).
inline constexpr char kLivenessService[] = "liveness";

class SkinServer {
 public:
  static Result<std::unique_ptr<SkinServer>> Start(const ServerOptions& options);
  ~SkinServer();

  int port() const { return port_; }
  // The metrics endpoint's port; 0 when --metrics-listen is not set.
  int metrics_port() const { return metrics_ ? metrics_->port() : 0; }
  Engine& engine() { return *engine_; }
  // NOT_SERVING, refuse new calls, let in-flight ones finish within `grace` (then cancel
  // them), finish the engine's queued frames. Idempotent.
  void Shutdown(std::chrono::milliseconds grace);
  void Wait();

 private:
  SkinServer() = default;
  void SetReady(bool ready);  // the readiness names of the health service
  // Listens on every --listen address and starts the gRPC server (service_ registered).
  Status ListenOn(const ServerOptions& options,
                  const std::shared_ptr<grpc::ServerCredentials>& tcp_credentials,
                  grpc::ServerBuilder& builder);
  // The shared-memory regions, the TCP credentials and the authorization policy, in that
  // order, then service_ over them and the GPU regions; the credentials are ListenOn's.
  Result<std::shared_ptr<grpc::ServerCredentials>> CreateService(const ServerOptions& options);
  // Builds engine_ and gives it to service_ (and the GPU regions' service); the default
  // backend must be one it has.
  Status StartEngine(const ServerOptions& options);
  Status StartFrameSocket(const ServerOptions& options);  // --frame-socket, once the engine is up
  std::string RenderMetrics() const;                      // on the metrics server's threads
  std::unique_ptr<RegionRegistry> regions_;  // null: shared memory off; outlives service_
  // null: no --authz-policy; outlives service_ and gpu_regions_' service
  std::unique_ptr<PolicyFile> policy_;
  std::unique_ptr<GpuRegionsOnServer> gpu_regions_;  // null: GPU regions off; outlives service_
  UnixPeers unix_peers_;  // the Unix-socket clients' credentials; outlives service_
  std::unique_ptr<SkinningService> service_;
  std::unique_ptr<grpc::Server> server_;
  // The unix: addresses; stopped before server_ shuts down, destroyed before it.
  std::vector<std::unique_ptr<UnixListener>> unix_listeners_;
  std::unique_ptr<Engine> engine_;
  // --frame-socket (null: off); its connections use service_ and engine_, so it goes first.
  std::unique_ptr<FrameSocket> frame_socket_;
  // Declared last: destroyed first, so no scrape outlives what it reads.
  std::unique_ptr<MetricsServer> metrics_;
  int port_ = 0;
  std::once_flag shutdown_once_;
};

}  // namespace skinserve::server
