#include "options/server_options.h"

#include <sched.h>

#include <fmt/format.h>

#include <algorithm>
#include <thread>

#include "options/cgroup_limits.h"

namespace skinserve::server {

namespace {

// The cores this process may run on (taskset, a container's cpuset).
int AffinityCores() {
  cpu_set_t set;
  return sched_getaffinity(0, sizeof(set), &set) == 0
             ? std::max(1, CPU_COUNT(&set))
             : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

// The cores this process may use: those it may run on, no more than its cgroup's CPU quota
// rounded up (a container's CPU limit), not the machine's.
int UsableCores() {
  int cores = AffinityCores();
  if (const auto quota = ReadCgroupLimits().whole_cpus()) cores = std::min(cores, *quota);
  return cores;
}

}  // namespace

int ServerOptions::ComputeThreads() const {
  if (threads > 0) return threads;
  return std::max(1, UsableCores() - 1);
}

std::string ServerOptions::DescribeSizing() const {
  const CgroupLimits cgroup = ReadCgroupLimits();
  const std::string cpu_limit =
      cgroup.cpus ? fmt::format("cgroup CPU limit {:g}", *cgroup.cpus) : "no cgroup CPU limit";
  const std::string memory_limit =
      cgroup.memory_bytes ? fmt::format("cgroup memory limit {} MiB", *cgroup.memory_bytes >> 20)
                          : "no cgroup memory limit";
  return fmt::format(
      "compute threads {} ({}usable cores {}: affinity {}, {}); in-flight budget {} MiB ({}{}); "
      "gRPC memory quota {} MiB{}",
      ComputeThreads(), threads > 0 ? "--threads; " : "", UsableCores(), AffinityCores(), cpu_limit,
      InflightBudgetBytes() >> 20, inflight_budget_mb > 0 ? "--inflight-budget-mb; " : "",
      memory_limit, GrpcMemoryBytes() >> 20, grpc_memory_mb > 0 ? " (--grpc-memory-mb)" : "");
}

MemoryEnvelope ServerOptions::Envelope() const {
  const auto enabled = [&](const char* id) {
    return backends.empty() || std::find(backends.begin(), backends.end(), id) != backends.end();
  };
  // The backends' prepared copies of a stored mesh: opencl's buffers (host memory on PoCL,
  // a whole copy); simd's joints and weights (at most ~45% of a float mesh's bytes).
  double mesh_copies = 1;
  std::string mesh_why = "the mesh";
  if (enabled("opencl")) {
    mesh_copies += 1;
    mesh_why += ", opencl's buffers";
  }
  if (enabled("simd") || enabled("simd-openmp")) {
    mesh_copies += 0.5;
    mesh_why += ", simd's joints and weights";
  }
  MemoryEnvelope envelope = EnvelopeMemory(memory_limit_mb);
  envelope.terms.push_back({.what = "stored meshes",
                            .flag = "--mesh-budget-mb",
                            .budget_bytes = mesh_budget_mb << 20,
                            .copies = mesh_copies,
                            .share = 0.30,
                            .why = mesh_why});
  envelope.terms.push_back({.what = "frames in flight, parsed requests",
                            .flag = "--inflight-budget-mb",
                            .budget_bytes = inflight_budget_mb << 20,
                            .copies = 1,
                            .share = 0.20,
                            .why = "charged as held"});
  envelope.terms.push_back({.what = "gRPC's buffers (resource quota)",
                            .flag = "--grpc-memory-mb",
                            .budget_bytes = grpc_memory_mb << 20,
                            .copies = 1,
                            .share = 0.10,
                            .why = "connections' reads, HTTP/2 state, messages"});
  envelope.terms.push_back({.what = "uploads",
                            .flag = "--upload-budget-mb",
                            .budget_bytes = upload_budget_mb << 20,
                            .copies = 2,
                            .share = 0.20,
                            .why = "the arrays, and the mesh built while they are held"});
  envelope.terms.push_back(
      {.what = "skeletons and clips",
       .flag = "--clip-budget-mb",
       .budget_bytes = clip_budget_mb << 20,
       .copies = 1,
       .share = 0.05,
       .why = "their compact bytes; the store's maps a few hundred bytes each"});
  if (!shm_dir.empty()) {
    envelope.terms.push_back({.what = "shared-memory regions",
                              .flag = "--shm-budget-mb",
                              .budget_bytes = shm_budget_mb << 20,
                              .copies = 1,
                              .share = 0.20,
                              .why = "tmpfs pages the server's writes fault in"});
  }
  DeriveBudgets(&envelope);
  return envelope;
}

uint64_t ServerOptions::InflightBudgetBytes() const {
  return Envelope().term("--inflight-budget-mb").budget_bytes;
}

RegionLimits ServerOptions::ToRegionLimits() const {
  RegionLimits limits;
  limits.dir = shm_dir;
  limits.budget_bytes = shm_dir.empty() ? 0 : Envelope().term("--shm-budget-mb").budget_bytes;
  limits.max_regions = shm_max_regions;
  limits.max_per_connection = shm_max_regions_per_connection;
  limits.idle_seconds = shm_idle_seconds;
  return limits;
}

Status ServerOptions::CheckSecurity() const {
  if (tls_cert.empty() != tls_key.empty()) {
    return InvalidArgument(
        fmt::format("--tls-cert and --tls-key go together: --tls-cert is '{}', --tls-key '{}'",
                    tls_cert, tls_key));
  }
  if (!tls_client_ca.empty() && tls_cert.empty()) {
    return InvalidArgument(
        fmt::format("--tls-client-ca '{}' needs --tls-cert and --tls-key: mutual TLS is TLS first",
                    tls_client_ca));
  }
  if (shm_over_tcp && tls_client_ca.empty()) {
    return InvalidArgument(
        "--shm-over-tcp needs mutual TLS (--tls-cert, --tls-key and --tls-client-ca): over TCP "
        "a region's owner is the identity of the client's certificate");
  }
  for (const auto& [flag, seconds] :
       {std::pair{"--tls-refresh-seconds", tls_refresh_seconds},
        std::pair{"--authz-refresh-seconds", authz_refresh_seconds}}) {
    if (!(seconds >= 1 && seconds <= 86400)) {
      return InvalidArgument(fmt::format("{} is {}: from 1 to 86400", flag, seconds));
    }
  }
  return Status::Ok();
}

uint64_t ServerOptions::UploadBudgetBytes() const {
  return Envelope().term("--upload-budget-mb").budget_bytes;
}

UploadLimits ServerOptions::ToUploadLimits() const {
  return {.max_uploads = max_uploads,
          .max_uploads_per_connection = max_uploads_per_connection,
          .budget_bytes = UploadBudgetBytes(),
          .idle_seconds = upload_idle_seconds,
          .deadline_seconds = upload_deadline_seconds};
}

StreamLimits ServerOptions::ToStreamLimits() const {
  return {.max_streams = max_streams, .idle_seconds = stream_idle_seconds};
}

SkinRequestLimits ServerOptions::ToRequestLimits() const {
  return {.max_tick_characters = max_tick_characters, .max_tick_bytes = max_tick_bytes};
}

uint64_t ServerOptions::GrpcMemoryBytes() const {
  return Envelope().term("--grpc-memory-mb").budget_bytes;
}

EngineOptions ServerOptions::ToEngineOptions() const {
  EngineOptions engine;
  engine.compute_threads = ComputeThreads();
  engine.queue_capacity = queue;
  engine.mesh_budget_bytes = Envelope().term("--mesh-budget-mb").budget_bytes;
  engine.clip_budget_bytes = Envelope().term("--clip-budget-mb").budget_bytes;
  engine.mesh.limits.max_vertices = max_vertices;
  engine.mesh.limits.max_joints = max_joints;
  engine.enabled_backends = backends;
  engine.opencl_device = opencl_device;
  engine.opencl_device_timing = opencl_device_timing;
  return engine;
}

namespace {

// Where it listens and what computes: the addresses, the compute threads and the backends.
void AddComputeOptions(CLI::App& app, ServerOptions& o) {
  app.add_option("--listen", o.listen,
                 "addresses to serve gRPC on, comma-separated: host:port, and unix:PATH for "
                 "clients on this host (e.g. 0.0.0.0:50051,unix:/run/skinserve/grpc.sock)")
      ->envname("SKINSERVE_LISTEN")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--threads", o.threads,
                 "compute threads doing skinning, for all streams together (0: one per usable "
                 "core less one, at least one: the rest is left to gRPC's threads; usable: the "
                 "cores this process may run on, at most its cgroup's CPU quota rounded up)")
      ->envname("SKINSERVE_THREADS")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--backends", o.backends,
                 "backend ids to enable, comma-separated (default: all of serial, openmp, sse, "
                 "sse-openmp, simd, simd-openmp, opencl, opencl-zerocopy, passthrough)")
      ->envname("SKINSERVE_BACKENDS")
      ->delimiter(',');
  app.add_option("--default-backend", o.default_backend, "backend used when a request names none")
      ->envname("SKINSERVE_DEFAULT_BACKEND")
      ->capture_default_str();
}

// The memory envelope, and the stored meshes that take its largest share.
void AddMemoryOptions(CLI::App& app, ServerOptions& o) {
  app.add_option("--memory-limit-mb", o.memory_limit_mb,
                 "the memory this server may use, MiB, that its budgets must fit together with "
                 "the copies they do not count (0: the cgroup's memory limit, else physical "
                 "memory); the server does not start when they do not fit")
      ->envname("SKINSERVE_MEMORY_LIMIT_MB")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_flag("--memory-envelope", o.print_memory_envelope,
               "print every budget with the copies it does not count, their sum and the memory "
               "it must fit, then exit: 0 when it fits, 1 when not");
  app.add_option("--mesh-budget-mb", o.mesh_budget_mb,
                 "memory for stored meshes, MiB; least recently used meshes are evicted beyond "
                 "(0: its share of the memory envelope, see --memory-envelope)")
      ->envname("SKINSERVE_MESH_BUDGET_MB")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--clip-budget-mb", o.clip_budget_mb,
                 "memory for uploaded skeletons and compact clips (SkinRequest.pose), MiB; "
                 "uploads beyond it are refused with RESOURCE_EXHAUSTED (0: its share of the "
                 "memory envelope)")
      ->envname("SKINSERVE_CLIP_BUDGET_MB")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--max-vertices", o.max_vertices, "largest vertex count a mesh may have")
      ->envname("SKINSERVE_MAX_VERTICES")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-joints", o.max_joints, "largest joint count a mesh may have (<= 65535)")
      ->envname("SKINSERVE_MAX_JOINTS")
      ->check(CLI::Range(1, 65535))
      ->capture_default_str();
}

// Frames and streams: the queue, the stream window, ticks, frames in flight and open streams.
void AddFrameOptions(CLI::App& app, ServerOptions& o) {
  app.add_option("--queue", o.queue,
                 "frames that may wait for a compute thread; beyond, RESOURCE_EXHAUSTED")
      ->envname("SKINSERVE_QUEUE")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--stream-window", o.stream_window,
                 "frames of one StreamSkin stream in flight at once; the server reads no "
                 "further ahead")
      ->envname("SKINSERVE_STREAM_WINDOW")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-tick-characters", o.max_tick_characters,
                 "characters one tick (SkinRequest.characters) may hold, nested ones included; "
                 "more: the tick is refused RESOURCE_EXHAUSTED")
      ->envname("SKINSERVE_MAX_TICK_CHARACTERS")
      ->check(CLI::Range(1u, 1u << 16))
      ->capture_default_str();
  app.add_option("--max-tick-bytes", o.max_tick_bytes,
                 "bytes one tick's request may hold (67108864 = 64 MiB by default); more: the "
                 "tick is refused RESOURCE_EXHAUSTED. The server takes messages up to this size "
                 "(at least 4 MiB), ticks only; a plain frame stays within 4 MiB")
      ->envname("SKINSERVE_MAX_TICK_BYTES")
      ->check(CLI::Range(uint64_t{1} << 10, uint64_t{1} << 31))
      ->capture_default_str();
  app.add_option("--inflight-budget-mb", o.inflight_budget_mb,
                 "memory for frames in flight across all streams (palettes, skinned vertices, "
                 "unwritten answers, parsed requests), MiB; frames beyond are answered "
                 "RESOURCE_EXHAUSTED (0: its share of the memory envelope)")
      ->envname("SKINSERVE_INFLIGHT_BUDGET_MB")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--max-streams-per-connection", o.max_streams_per_connection,
                 "calls one client connection may have open at once (HTTP/2 "
                 "MAX_CONCURRENT_STREAMS); further calls wait at the client")
      ->envname("SKINSERVE_MAX_STREAMS_PER_CONNECTION")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-streams", o.max_streams,
                 "StreamSkin streams open at once over all connections; beyond, a new stream "
                 "is refused with RESOURCE_EXHAUSTED")
      ->envname("SKINSERVE_MAX_STREAMS")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--stream-idle-seconds", o.stream_idle_seconds,
                 "a StreamSkin stream with no frame in flight that sends none for this long "
                 "(seconds) is ended with UNAVAILABLE (every frame it sent was answered; the "
                 "client may open a new stream)")
      ->envname("SKINSERVE_STREAM_IDLE_SECONDS")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
}

// Uploads in progress: their memory, how many, and how long they may take.
void AddUploadOptions(CLI::App& app, ServerOptions& o) {
  app.add_option("--upload-budget-mb", o.upload_budget_mb,
                 "memory for the arrays of uploads in progress, all together, MiB; taken as "
                 "chunks arrive (a header costs nothing; an upload holds up to 1.5 times its "
                 "mesh's size while its arrays grow); a chunk beyond it ends its upload with "
                 "RESOURCE_EXHAUSTED (0: its share of the memory envelope)")
      ->envname("SKINSERVE_UPLOAD_BUDGET_MB")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--max-uploads", o.max_uploads,
                 "UploadMesh calls open at once over all connections; beyond, a new upload is "
                 "refused with RESOURCE_EXHAUSTED")
      ->envname("SKINSERVE_MAX_UPLOADS")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-uploads-per-connection", o.max_uploads_per_connection,
                 "UploadMesh calls one client connection may have open at once; beyond, a new "
                 "upload is refused with RESOURCE_EXHAUSTED")
      ->envname("SKINSERVE_MAX_UPLOADS_PER_CONNECTION")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--upload-idle-seconds", o.upload_idle_seconds,
                 "an upload that makes no progress for this long (seconds; neither its header "
                 "nor array bytes arrive: empty chunks do not count) is ended with "
                 "RESOURCE_EXHAUSTED and what it sent is dropped")
      ->envname("SKINSERVE_UPLOAD_IDLE_SECONDS")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--upload-deadline-seconds", o.upload_deadline_seconds,
                 "an upload still open this long after it began (seconds), however it "
                 "progresses, is ended with RESOURCE_EXHAUSTED and what it sent is dropped")
      ->envname("SKINSERVE_UPLOAD_DEADLINE_SECONDS")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
}

// Operations: logs, the OpenCL device, draining, the port file and the metrics endpoint.
void AddOperationOptions(CLI::App& app, ServerOptions& o) {
  app.add_option("--log-level", o.log_level, "trace, debug, info, warn, error or off")
      ->envname("SKINSERVE_LOG_LEVEL")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "critical", "off"}))
      ->capture_default_str();
  app.add_option("--opencl-device", o.opencl_device,
                 "device of the OpenCL backends: cpu, gpu, or part of a platform or device name "
                 "(default: the first CPU device, else the first device); no match is a start-up "
                 "error listing the devices found")
      ->envname("SKINSERVE_OPENCL_DEVICE");
  app.add_flag("--opencl-device-timing", o.opencl_device_timing,
               "OpenCL frames report their device time (ServerTiming.device_kernel_ns and "
               "device_transfer_ns; 0 without): profiled queues, which cost a small GPU frame "
               "about 14 us more on an H200")
      ->envname("SKINSERVE_OPENCL_DEVICE_TIMING");
  app.add_option("--drain-seconds", o.drain_seconds,
                 "on SIGTERM or SIGINT, how long in-flight frames may take to finish")
      ->envname("SKINSERVE_DRAIN_SECONDS")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--log-format", o.log_format,
                 "text, or json: one JSON object per line (time, level, thread, message) for "
                 "log pipelines")
      ->envname("SKINSERVE_LOG_FORMAT")
      ->check(CLI::IsMember({"text", "json"}))
      ->capture_default_str();
  app.add_option("--port-file", o.port_file,
                 "once serving, write the gRPC port (a number and a newline) to this file: "
                 "start with --listen HOST:0 and read it, instead of racing for a free port")
      ->envname("SKINSERVE_PORT_FILE");
  app.add_option("--metrics-listen", o.metrics_listen,
                 "address:port to serve Prometheus metrics on (GET /metrics); empty: off")
      ->envname("SKINSERVE_METRICS_LISTEN");
}

// The same-host data plane (docs/serving/shared-memory.md): where clients' regions live, what
// they may map together, how many, when an unused one is dropped, and over which transports.
void AddSharedMemoryOptions(CLI::App& app, ServerOptions& o) {
  app.add_option("--shm-dir", o.shm_dir,
                 "directory of the shared-memory regions clients on this host may register "
                 "(their files must be inside it); empty: shared memory off")
      ->envname("SKINSERVE_SHM_DIR")
      ->capture_default_str();
  app.add_option("--shm-budget-mb", o.shm_budget_mb,
                 "bytes all registered regions may map together, MiB (0: its share of the "
                 "memory envelope); beyond, RegisterRegion is refused")
      ->envname("SKINSERVE_SHM_BUDGET_MB")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--shm-max-regions", o.shm_max_regions, "regions registered at once, in all")
      ->envname("SKINSERVE_SHM_MAX_REGIONS")
      ->check(CLI::Range(1, 4096))
      ->capture_default_str();
  app.add_option("--shm-max-regions-per-connection", o.shm_max_regions_per_connection,
                 "regions one client may register (one owner: a process on the Unix socket, a "
                 "certificate identity over TCP)")
      ->envname("SKINSERVE_SHM_MAX_REGIONS_PER_CONNECTION")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--shm-idle-seconds", o.shm_idle_seconds,
                 "a region no frame names for this long is unregistered and unmapped (a client "
                 "that went away leaves nothing mapped)")
      ->envname("SKINSERVE_SHM_IDLE_SECONDS")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--shm-over-tcp", o.shm_over_tcp,
                 "serve the region RPCs (and frames into regions) over TCP too, to clients with "
                 "a certificate (needs --tls-client-ca), whose identity owns their regions and "
                 "who may map files the server's uid owns; off: only clients on a unix: "
                 "address, owned by their process, mapping files their uid owns")
      ->envname("SKINSERVE_SHM_OVER_TCP")
      ->capture_default_str();
}

// The frame socket (docs/serving/frame-socket.md).
void AddFrameSocketOptions(CLI::App& app, ServerOptions& o) {
  app.add_option("--frame-socket", o.frame_socket,
                 "Unix socket path where clients on this host send StreamSkin's requests "
                 "without gRPC (one thread per connection reads, skins and answers a frame); "
                 "empty: off")
      ->envname("SKINSERVE_FRAME_SOCKET");
  app.add_option("--frame-socket-max-connections", o.frame_socket_max_connections,
                 "frame-socket connections served at once (a thread each); one more is "
                 "refused with RESOURCE_EXHAUSTED")
      ->envname("SKINSERVE_FRAME_SOCKET_MAX_CONNECTIONS")
      ->check(CLI::Range(1, 4096))
      ->capture_default_str();
}

// GPU regions (docs/serving/gpu-regions.md): the fd handoff socket and the limits of what
// clients may import.
void AddGpuRegionOptions(CLI::App& app, ServerOptions& o) {
  app.add_option("--gpu-fd-socket", o.gpu_fd_socket,
                 "Unix socket path where clients on this host hand over exported GPU buffers' "
                 "file descriptors for GPU regions (the GpuRegions service); empty: GPU regions "
                 "off")
      ->envname("SKINSERVE_GPU_FD_SOCKET");
  app.add_option("--gpu-region-budget-mb", o.gpu_region_budget_mb,
                 "bytes all GPU regions may import together, MiB (GPU memory: not part of the "
                 "memory envelope)")
      ->envname("SKINSERVE_GPU_REGION_BUDGET_MB")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--gpu-max-regions", o.gpu_max_regions, "GPU regions registered at once, in all")
      ->envname("SKINSERVE_GPU_MAX_REGIONS")
      ->check(CLI::Range(1, 4096))
      ->capture_default_str();
}

// Transport security and authorization (docs/security.md): TLS files, the authorization
// policy, how often each is re-read, and reflection.
void AddSecurityOptions(CLI::App& app, ServerOptions& o) {
  app.add_option("--tls-cert", o.tls_cert,
                 "PEM certificate chain of the server: TLS on every host:port address (unix: "
                 "addresses stay plaintext, guarded by their folder's permissions); re-read when "
                 "the file changes")
      ->envname("SKINSERVE_TLS_CERT");
  app.add_option("--tls-key", o.tls_key, "PEM private key of --tls-cert")
      ->envname("SKINSERVE_TLS_KEY");
  app.add_option("--tls-client-ca", o.tls_client_ca,
                 "PEM CA certificates: mutual TLS, every TCP client must present a certificate "
                 "they signed (its subject and SANs are what --authz-policy names)")
      ->envname("SKINSERVE_TLS_CLIENT_CA");
  app.add_option("--tls-refresh-seconds", o.tls_refresh_seconds,
                 "how often the --tls-* files are checked for changes; new connections use what "
                 "was read last, open ones keep theirs")
      ->envname("SKINSERVE_TLS_REFRESH_SECONDS")
      ->capture_default_str();
  app.add_option("--authz-policy", o.authz_policy,
                 "authorization policy in gRPC's format (JSON: allow_rules and deny_rules by "
                 "method path and client certificate principal), checked when each call of "
                 "skinserve.v1.Skinning starts (health stays open to all); calls it denies end "
                 "PERMISSION_DENIED; re-read when the file changes (empty: every client may "
                 "call every method)")
      ->envname("SKINSERVE_AUTHZ_POLICY");
  app.add_option("--authz-refresh-seconds", o.authz_refresh_seconds,
                 "how often the --authz-policy file is checked for changes")
      ->envname("SKINSERVE_AUTHZ_REFRESH_SECONDS")
      ->capture_default_str();
  app.add_option("--reflection", o.reflection,
                 "serve gRPC server reflection (grpc.reflection.v1alpha), which lists the "
                 "service's methods to anyone who may call it")
      ->envname("SKINSERVE_REFLECTION")
      ->capture_default_str();
}

// Connection hygiene (docs/deployment/scale-out.md#connections, docs/security.md#connections):
// keepalive, connection age, idle and handshake limits, and gRPC's own memory quota.
void AddConnectionOptions(CLI::App& app, ServerOptions& o) {
  app.add_option("--keepalive-seconds", o.keepalive_seconds,
                 "ping an idle connection after this long, to find peers that are gone")
      ->envname("SKINSERVE_KEEPALIVE_SECONDS")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--keepalive-timeout-seconds", o.keepalive_timeout_seconds,
                 "close a connection whose ping is not answered within this long")
      ->envname("SKINSERVE_KEEPALIVE_TIMEOUT_SECONDS")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-connection-age-seconds", o.max_connection_age_seconds,
                 "ask clients to reconnect (GOAWAY) after this long (+-10% jitter), so they "
                 "re-resolve and spread onto new replicas; 0: never")
      ->envname("SKINSERVE_MAX_CONNECTION_AGE_SECONDS")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--max-connection-age-grace-seconds", o.max_connection_age_grace_seconds,
                 "after the GOAWAY, how long calls in flight may finish before the connection "
                 "is closed (longer than a frame; a longer stream ends UNAVAILABLE and the "
                 "client library resumes it elsewhere)")
      ->envname("SKINSERVE_MAX_CONNECTION_AGE_GRACE_SECONDS")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--connection-idle-seconds", o.connection_idle_seconds,
                 "close (GOAWAY) a connection with no call open for this long, seconds; "
                 "clients reconnect on their next call (0: never)")
      ->envname("SKINSERVE_CONNECTION_IDLE_SECONDS")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--handshake-timeout-seconds", o.handshake_timeout_seconds,
                 "drop a new connection that has not completed its TLS handshake and sent its "
                 "HTTP/2 settings within this long, seconds")
      ->envname("SKINSERVE_HANDSHAKE_TIMEOUT_SECONDS")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--grpc-memory-mb", o.grpc_memory_mb,
                 "memory gRPC's own buffers for all connections may take (its resource quota), "
                 "MiB; near it gRPC closes idle connections, shrinks its windows and cancels "
                 "calls (0: its share of the memory envelope)")
      ->envname("SKINSERVE_GRPC_MEMORY_MB")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
}

}  // namespace

// In the order --help lists them.
void AddServerOptions(CLI::App& app, ServerOptions& o) {
  AddComputeOptions(app, o);
  AddMemoryOptions(app, o);
  AddFrameOptions(app, o);
  AddUploadOptions(app, o);
  AddOperationOptions(app, o);
  AddSharedMemoryOptions(app, o);
  AddFrameSocketOptions(app, o);
  AddGpuRegionOptions(app, o);
  AddSecurityOptions(app, o);
  AddConnectionOptions(app, o);
}

}  // namespace skinserve::server
