// Every server option, settable by flag or by environment variable (for containers).
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

#include "frames/skin_request_reader.h"
#include "options/memory_envelope.h"
#include "rpc/open_streams.h"
#include "rpc/open_uploads.h"
#include "shm/region_registry.h"
#include "skinserve/engine/engine.h"

namespace skinserve::server {

struct ServerOptions {
  // Addresses to serve gRPC on: host:port, and unix:PATH for same-host clients.
  std::vector<std::string> listen = {"127.0.0.1:50051"};
  int threads = 0;                    // 0: one per core less one (see ComputeThreads)
  std::vector<std::string> backends;  // empty: all
  std::string default_backend = "sse-openmp";
  uint64_t mesh_budget_mb = 0;  // 0: its share of the memory envelope
  // Skeletons and compact clips (UploadSkeleton, UploadClip); uploads beyond are refused.
  uint64_t clip_budget_mb = 64;  // 0: its share of the memory envelope
  uint32_t max_vertices = 4'000'000;
  uint32_t max_joints = 1024;
  // 1024: at 256, open-loop single-character streams were refused for a full queue with
  // the CPU half idle (docs/serving/index.md#scheduler)
  std::size_t queue = 1024;
  int stream_window = 16;
  // Ticks (SkinRequest.characters): characters in one request, and its bytes.
  uint32_t max_tick_characters = 256;
  uint64_t max_tick_bytes = 64ull << 20;
  // HTTP/2 streams (calls) one client connection may have open at once; more wait at the
  // client until one ends (gRPC's GRPC_ARG_MAX_CONCURRENT_STREAMS).
  int max_streams_per_connection = 128;
  // StreamSkin streams open at once over all connections; more are refused.
  std::size_t max_streams = 1024;
  // A stream with no frame in flight that sends none for this long is ended (UNAVAILABLE).
  double stream_idle_seconds = 120;
  std::string log_level = "info";
  double drain_seconds = 10;
  std::string log_format = "text";  // text or json (one JSON object per line)
  std::string metrics_listen;       // empty: no metrics endpoint
  std::string port_file;            // empty: none; else the bound gRPC port is written there
  // Connection hygiene (docs/deployment/scale-out.md#connections): keepalive pings find
  // dead peers; a maximum connection age makes clients reconnect, and so re-resolve, so
  // that replicas added by a scale-up get their share; the grace lets the frames in flight
  // finish.
  double keepalive_seconds = 30;
  double keepalive_timeout_seconds = 10;
  double max_connection_age_seconds = 300;  // 0: connections never age out
  double max_connection_age_grace_seconds = 30;
  // What gRPC 1.51 offers against many or idle connections (it has no cap on their
  // number; docs/security.md#connections): a connection with no call this long is closed
  // (0: never), one that has not spoken HTTP/2 within the handshake timeout is dropped, and
  // gRPC's own buffers for all connections share one memory quota.
  double connection_idle_seconds = 120;
  double handshake_timeout_seconds = 10;
  uint64_t grpc_memory_mb = 0;        // 0: its share of the memory envelope
  uint64_t inflight_budget_mb = 0;    // 0: its share of the memory envelope
  std::string opencl_device;          // "": the first CPU device (PoCL), else the first device
  bool opencl_device_timing = false;  // profiled OpenCL queues: ServerTiming.device_*_ns
  // The same-host data plane (docs/serving/shared-memory.md): where clients' regions live (empty:
  // off), what they may map together, how many, and when an unused one is dropped.
  std::string shm_dir = "/dev/shm";
  uint64_t shm_budget_mb = 0;  // 0: its share of the memory envelope
  uint32_t shm_max_regions = 256;
  uint32_t shm_max_regions_per_connection = 16;
  double shm_idle_seconds = 60;
  // Region RPCs (and frames into regions) over TCP, owned by the client certificate's
  // identity: needs mutual TLS. Off: only Unix-socket clients, owned by their process.
  bool shm_over_tcp = false;
  // The frame socket (docs/serving/frame-socket.md): a Unix socket where same-host clients
  // send StreamSkin's requests without gRPC (empty: off), and the connections it serves at
  // once (a thread each).
  std::string frame_socket;
  uint32_t frame_socket_max_connections = 256;
  // GPU regions (docs/serving/gpu-regions.md): the socket clients hand their exported GPU
  // buffers' fds over (empty: off), the bytes all imports may hold, and how many.
  std::string gpu_fd_socket;
  uint64_t gpu_region_budget_mb = 8192;
  uint32_t gpu_max_regions = 64;
  // Transport security (docs/security.md): TLS on every TCP address when a certificate is
  // given, mutual TLS when a client CA is given too; unix: addresses stay plaintext. The
  // files are re-read every tls_refresh_seconds, so mounted secrets rotate without a restart.
  std::string tls_cert, tls_key, tls_client_ca;
  double tls_refresh_seconds = 60;
  // An authorization policy in gRPC's format (authz_policy.h), re-read every
  // authz_refresh_seconds; empty: none.
  std::string authz_policy;
  double authz_refresh_seconds = 60;
  bool reflection = true;
  // Uploads (see OpenUploads): what their arrays may hold together, how many may be open
  // at once (over all connections and per connection), how long one may make no progress
  // (empty chunks are no progress), and how long one may take in all.
  uint64_t upload_budget_mb = 0;  // 0: its share of the memory envelope
  std::size_t max_uploads = 16;
  std::size_t max_uploads_per_connection = 4;
  double upload_idle_seconds = 10;
  double upload_deadline_seconds = 300;

  // The memory the budgets must fit (memory_envelope.h): 0 reads the cgroup's limit, else
  // physical memory.
  uint64_t memory_limit_mb = 0;
  bool print_memory_envelope = false;  // --memory-envelope: print it and exit

  // Every budget with the copies it does not count, against the memory this process may
  // use; budgets left at 0 are derived here.
  MemoryEnvelope Envelope() const;
  EngineOptions ToEngineOptions() const;
  // --threads, or by default one per core less one (at least one): gRPC's threads do most
  // of a frame's work (messages, copies, the socket) and must not wait for cores that
  // compute threads hold.
  int ComputeThreads() const;
  // What the threads and the in-flight budget were sized from, for the start-up log:
  // "compute threads 1 (usable cores 2: affinity 2, cgroup CPU limit 1.5), ...".
  std::string DescribeSizing() const;
  uint64_t InflightBudgetBytes() const;
  RegionLimits ToRegionLimits() const;
  uint64_t UploadBudgetBytes() const;
  UploadLimits ToUploadLimits() const;
  StreamLimits ToStreamLimits() const;
  // The limits a SkinRequest is read under (ticks' included; max_instances from the engine).
  SkinRequestLimits ToRequestLimits() const;
  uint64_t GrpcMemoryBytes() const;
  // The combinations of the TLS and policy options that cannot work, each named.
  Status CheckSecurity() const;
};

// Registers the options on `app`, each with its SKINSERVE_* environment variable.
void AddServerOptions(CLI::App& app, ServerOptions& options);

}  // namespace skinserve::server
