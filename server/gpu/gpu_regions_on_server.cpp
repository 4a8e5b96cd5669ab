#include "gpu/gpu_regions_on_server.h"

#include <spdlog/spdlog.h>

namespace skinserve::server {

Result<std::unique_ptr<GpuRegionsOnServer>> GpuRegionsOnServer::Start(const ServerOptions& options,
                                                                      const UnixPeers* peers,
                                                                      const PolicyFile* policy) {
  if (options.gpu_fd_socket.empty()) return std::unique_ptr<GpuRegionsOnServer>();
  auto handoff = FdHandoff::Listen(options.gpu_fd_socket);
  if (!handoff.ok()) return handoff.status();
  auto on = std::make_unique<GpuRegionsOnServer>();
  on->handoff = std::move(handoff).value();
  on->registry = std::make_unique<GpuRegionRegistry>(
      GpuRegionLimits{.budget_bytes = options.gpu_region_budget_mb << 20,
                      .max_regions = options.gpu_max_regions,
                      .max_per_owner = options.shm_max_regions_per_connection,
                      .idle_seconds = options.shm_idle_seconds});
  on->service = std::make_unique<GpuRegionService>(on->registry.get(), on->handoff.get(), peers,
                                                   policy, options.default_backend);
  spdlog::info("GPU regions on: fds handed over on {}, up to {} MiB imported",
               options.gpu_fd_socket, options.gpu_region_budget_mb);
  return on;
}

}  // namespace skinserve::server
