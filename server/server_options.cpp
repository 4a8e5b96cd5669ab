#include "server_options.h"

namespace skinserve::server {

EngineOptions ServerOptions::ToEngineOptions() const {
  EngineOptions engine;
  engine.compute_threads = threads;
  engine.queue_capacity = queue;
  engine.mesh_budget_bytes = mesh_budget_mb << 20;
  engine.mesh.limits.max_vertices = max_vertices;
  engine.mesh.limits.max_joints = max_joints;
  engine.enabled_backends = backends;
  return engine;
}

void AddServerOptions(CLI::App& app, ServerOptions& o) {
  app.add_option("--listen", o.listen, "address:port to serve gRPC on")
      ->envname("SKINSERVE_LISTEN")
      ->capture_default_str();
  app.add_option("--threads", o.threads,
                 "compute threads doing skinning, for all streams together (0: one per core)")
      ->envname("SKINSERVE_THREADS")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--backends", o.backends,
                 "backend ids to enable, comma-separated (default: all of serial, openmp, sse, "
                 "sse-openmp, opencl, opencl-zerocopy, passthrough)")
      ->envname("SKINSERVE_BACKENDS")
      ->delimiter(',');
  app.add_option("--default-backend", o.default_backend, "backend used when a request names none")
      ->envname("SKINSERVE_DEFAULT_BACKEND")
      ->capture_default_str();
  app.add_option("--mesh-budget-mb", o.mesh_budget_mb,
                 "memory for stored meshes, MiB; least recently used meshes are evicted beyond")
      ->envname("SKINSERVE_MESH_BUDGET_MB")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-vertices", o.max_vertices, "largest vertex count a mesh may have")
      ->envname("SKINSERVE_MAX_VERTICES")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-joints", o.max_joints, "largest joint count a mesh may have (<= 65535)")
      ->envname("SKINSERVE_MAX_JOINTS")
      ->check(CLI::Range(1, 65535))
      ->capture_default_str();
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
  app.add_option("--log-level", o.log_level, "trace, debug, info, warn, error or off")
      ->envname("SKINSERVE_LOG_LEVEL")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "critical", "off"}))
      ->capture_default_str();
  app.add_option("--drain-seconds", o.drain_seconds,
                 "on SIGTERM or SIGINT, how long in-flight frames may take to finish")
      ->envname("SKINSERVE_DRAIN_SECONDS")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
}

}  // namespace skinserve::server
