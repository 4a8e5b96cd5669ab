// Every server option, settable by flag or by environment variable (for containers).
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

#include "skinserve/core/engine.h"

namespace skinserve::server {

struct ServerOptions {
  std::string listen = "127.0.0.1:50051";
  int threads = 0;                    // 0: one per core
  std::vector<std::string> backends;  // empty: all
  std::string default_backend = "sse-openmp";
  uint64_t mesh_budget_mb = 4096;
  uint32_t max_vertices = 4'000'000;
  uint32_t max_joints = 1024;
  std::size_t queue = 256;
  int stream_window = 16;
  // HTTP/2 streams (calls) one client connection may have open at once; more wait at the
  // client until one ends (gRPC's GRPC_ARG_MAX_CONCURRENT_STREAMS).
  int max_streams_per_connection = 128;
  // StreamSkin streams open at once over all connections; more are refused.
  std::size_t max_streams = 1024;
  std::string log_level = "info";
  double drain_seconds = 10;

  EngineOptions ToEngineOptions() const;
};

// Registers the options on `app`, each with its SKINSERVE_* environment variable.
void AddServerOptions(CLI::App& app, ServerOptions& options);

}  // namespace skinserve::server
