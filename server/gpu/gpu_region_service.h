// The GpuRegions service (skinning.proto): registers a client's exported GPU buffer,
// handed over the fd-handoff socket (fd_handoff.h), with the engine's backend, and
// unregisters and lists them. Only callers on the server's Unix socket own GPU regions
// (RegionOwnerOf with TCP refused: a descriptor cannot cross TCP anyway). Each call is
// checked against the --authz-policy first, as the Skinning service's are.
#pragma once

#include <atomic>

#include "gpu/fd_handoff.h"
#include "gpu/gpu_region_registry.h"
#include "security/authz_policy_file.h"
#include "shm/region_owner.h"
#include "skinserve/engine/engine.h"
#include "skinserve/v1/skinning.grpc.pb.h"

namespace skinserve::server {

class GpuRegionService final : public v1::GpuRegions::CallbackService {
 public:
  // All four outlive the service (`policy` may be null: no --authz-policy);
  // `default_backend` is the server's --backend.
  GpuRegionService(GpuRegionRegistry* regions, FdHandoff* handoff, const UnixPeers* peers,
                   const PolicyFile* policy, std::string default_backend)
      : regions_(regions),
        handoff_(handoff),
        access_{.unix_peers = peers, .over_tcp = false},
        policy_(policy),
        default_backend_(std::move(default_backend)) {}
  void SetEngine(Engine* engine) { engine_.store(engine); }

  grpc::ServerUnaryReactor* RegisterGpuRegion(grpc::CallbackServerContext* context,
                                              const v1::RegisterGpuRegionRequest* request,
                                              v1::GpuRegionInfo* response) override;
  grpc::ServerUnaryReactor* UnregisterGpuRegion(grpc::CallbackServerContext* context,
                                                const v1::UnregisterGpuRegionRequest* request,
                                                v1::UnregisterGpuRegionResponse* response) override;
  grpc::ServerUnaryReactor* ListGpuRegions(grpc::CallbackServerContext* context,
                                           const v1::ListGpuRegionsRequest* request,
                                           v1::ListGpuRegionsResponse* response) override;

 private:
  // The registration once the caller is known: the token's fd imported, or why not.
  // The --authz-policy's answer for `method` ("RegisterGpuRegion") and this call's peer.
  Status Authorize(const grpc::CallbackServerContext& context, const char* method) const;
  Result<GpuRegionInfo> Register(const v1::RegisterGpuRegionRequest& request,
                                 const RegionOwner& owner, Engine& engine);

  GpuRegionRegistry* const regions_;
  FdHandoff* const handoff_;
  const RegionAccessPolicy access_;
  const PolicyFile* const policy_;
  const std::string default_backend_;
  std::atomic<Engine*> engine_{nullptr};
};

}  // namespace skinserve::server
