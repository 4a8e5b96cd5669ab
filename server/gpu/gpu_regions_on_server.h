// What a server runs for GPU regions (docs/serving/gpu-regions.md), on when --gpu-fd-socket
// names a path: the fd-handoff socket, the registry and the GpuRegions service.
#pragma once

#include <memory>

#include "gpu/fd_handoff.h"
#include "gpu/gpu_region_registry.h"
#include "gpu/gpu_region_service.h"
#include "options/server_options.h"

namespace skinserve::server {

struct GpuRegionsOnServer {
  // Null when --gpu-fd-socket is empty (GPU regions off); else listening, or why not.
  // `peers` and `policy` (null: no --authz-policy) outlive it.
  static Result<std::unique_ptr<GpuRegionsOnServer>> Start(const ServerOptions& options,
                                                           const UnixPeers* peers,
                                                           const PolicyFile* policy);
  std::unique_ptr<FdHandoff> handoff;
  std::unique_ptr<GpuRegionRegistry> registry;
  std::unique_ptr<GpuRegionService> service;
};

}  // namespace skinserve::server
