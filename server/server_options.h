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
  std::string log_level = "info";
  double drain_seconds = 10;
  std::string opencl_device;  // "": the first CPU device (PoCL), else the first device

  EngineOptions ToEngineOptions() const;
};

// Registers the options on `app`, each with its SKINSERVE_* environment variable.
void AddServerOptions(CLI::App& app, ServerOptions& options);

}  // namespace skinserve::server
