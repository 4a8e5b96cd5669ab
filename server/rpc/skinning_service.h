// The Skinning service: each RPC translates wire messages to the engine and back.
#pragma once

#include <atomic>
#include <string>

#include "frames/inflight_budget.h"
#include "frames/skin_request_reader.h"
#include "observability/server_snapshot.h"
#include "rpc/open_streams.h"
#include "rpc/open_uploads.h"
#include "security/authz_policy_file.h"
#include "shm/region_registry.h"
#include "skinserve/engine/engine.h"
#include "skinserve/v1/skinning.grpc.pb.h"
#include "socket/frame_socket_access.h"

namespace skinserve::server {

// Skin and StreamSkin are raw (grpc::ByteBuffer) methods: their answers are sent as
// slices of the frame jobs' buffers, which gRPC's protobuf serialization would copy.
using SkinningCallbackService = v1::Skinning::WithCallbackMethod_UploadMesh<
    v1::Skinning::WithCallbackMethod_GetMesh<v1::Skinning::WithCallbackMethod_DeleteMesh<
        v1::Skinning::WithRawCallbackMethod_Skin<v1::Skinning::WithRawCallbackMethod_StreamSkin<
            v1::Skinning::WithCallbackMethod_ListBackends<
                v1::Skinning::WithCallbackMethod_GetServerStats<
                    v1::Skinning::WithCallbackMethod_RegisterRegion<
                        v1::Skinning::WithCallbackMethod_UnregisterRegion<
                            v1::Skinning::WithCallbackMethod_ListRegions<
                                v1::Skinning::WithCallbackMethod_UploadSkeleton<
                                    v1::Skinning::WithCallbackMethod_UploadClip<
                                        v1::Skinning::WithCallbackMethod_DeleteClip<
                                            v1::Skinning::Service>>>>>>>>>>>>>;

class SkinningService final : public SkinningCallbackService {
 public:
  // `regions` (null: shared memory is off) and `region_access.unix_peers` outlive the service.
  SkinningService(std::string default_backend, int stream_window, const StreamLimits& stream_limits,
                  uint64_t inflight_budget_bytes, const UploadLimits& upload_limits,
                  RegionRegistry* regions, const PolicyFile* policy = nullptr,
                  RegionAccessPolicy region_access = {})
      : default_backend_(std::move(default_backend)),
        stream_window_(stream_window),
        open_streams_(stream_limits),
        budget_(inflight_budget_bytes),
        regions_(regions),
        region_access_(region_access),
        policy_(policy),
        open_uploads_(upload_limits) {}
  // The limits Skin and StreamSkin read requests under (ticks'); max_instances comes from
  // the engine. Set before serving.
  void SetRequestLimits(const SkinRequestLimits& limits) { request_limits_ = limits; }
  // Until the engine is set, every RPC answers UNAVAILABLE (the server is warming up).
  void SetEngine(Engine* engine) { engine_.store(engine); }
  // GPU regions (gpu/): frames may name them once set (before serving); null: off.
  void SetGpuRegions(GpuRegionRegistry* gpu_regions) { gpu_regions_ = gpu_regions; }
  // Shutdown: open streams answer the frames they have read and end UNAVAILABLE; new
  // streams are refused. Unary calls and Skin finish as usual.
  void Drain() { open_streams_.DrainAll(); }
  bool WaitUntilStreamsEnded(std::chrono::steady_clock::time_point deadline) {
    return open_streams_.WaitUntilAllEnded(deadline);
  }
  std::size_t OpenStreamCount() const { return open_streams_.count(); }
  // What a frame-socket connection from `peer` serves with (socket/frame_socket.h): this
  // service's engine, budget, limits and regions, and the policy's verdict on StreamSkin.
  FrameSocketAccess FrameSocketAccessFor(const UnixPeerCredentials& peer);
  FrameSocketCounters* frame_socket_counters() { return &frame_socket_counters_; }
  // Everything the server reports, taken at once for /metrics and GetServerStats.
  ServerSnapshot Snapshot() const;
  // SERVING or not (starting, draining), as the health service says.
  void SetServing(bool serving) { serving_.store(serving); }

  grpc::ServerReadReactor<v1::UploadMeshRequest>* UploadMesh(grpc::CallbackServerContext*,
                                                             v1::MeshInfo* response) override;
  grpc::ServerUnaryReactor* GetMesh(grpc::CallbackServerContext* context,
                                    const v1::GetMeshRequest* request,
                                    v1::MeshInfo* response) override;
  grpc::ServerUnaryReactor* DeleteMesh(grpc::CallbackServerContext* context,
                                       const v1::DeleteMeshRequest* request,
                                       v1::DeleteMeshResponse* response) override;
  grpc::ServerWriteReactor<grpc::ByteBuffer>* Skin(grpc::CallbackServerContext*,
                                                   const grpc::ByteBuffer* request) override;
  grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* StreamSkin(
      grpc::CallbackServerContext*) override;
  grpc::ServerUnaryReactor* ListBackends(grpc::CallbackServerContext* context,
                                         const v1::ListBackendsRequest* request,
                                         v1::ListBackendsResponse* response) override;
  grpc::ServerUnaryReactor* GetServerStats(grpc::CallbackServerContext* context,
                                           const v1::GetServerStatsRequest* request,
                                           v1::ServerStats* response) override;
  grpc::ServerUnaryReactor* RegisterRegion(grpc::CallbackServerContext* context,
                                           const v1::RegisterRegionRequest* request,
                                           v1::RegionInfo* response) override;
  grpc::ServerUnaryReactor* UnregisterRegion(grpc::CallbackServerContext* context,
                                             const v1::UnregisterRegionRequest* request,
                                             v1::UnregisterRegionResponse* response) override;
  grpc::ServerUnaryReactor* ListRegions(grpc::CallbackServerContext* context,
                                        const v1::ListRegionsRequest* request,
                                        v1::ListRegionsResponse* response) override;
  // The animation RPCs (rpc/animation_uploads.cpp): the engine's AnimationStore.
  grpc::ServerUnaryReactor* UploadSkeleton(grpc::CallbackServerContext* context,
                                           const v1::UploadSkeletonRequest* request,
                                           v1::SkeletonInfo* response) override;
  grpc::ServerUnaryReactor* UploadClip(grpc::CallbackServerContext* context,
                                       const v1::UploadClipRequest* request,
                                       v1::ClipInfo* response) override;
  grpc::ServerUnaryReactor* DeleteClip(grpc::CallbackServerContext* context,
                                       const v1::DeleteClipRequest* request,
                                       v1::DeleteClipResponse* response) override;

 private:
  // OK when there is no policy or it allows `method` ("UploadMesh") for this call's peer.
  Status Authorize(const grpc::CallbackServerContext& context, const char* method) const;
  // The registry and who this call's peer is to it, for the frames of a Skin or StreamSkin.
  RegionCaller RegionCallerOf(const grpc::CallbackServerContext& context) const;

  std::atomic<Engine*> engine_{nullptr};
  std::atomic<bool> serving_{false};
  const std::string default_backend_;
  const int stream_window_;
  SkinRequestLimits request_limits_;
  OpenStreams open_streams_;  // the cap on streams, their idle watchdog, the drain
  InflightBudget budget_;     // the bytes of frames in flight, all streams and Skin calls
  RegionRegistry* const regions_;
  GpuRegionRegistry* gpu_regions_ = nullptr;   // null: GPU regions off
  const RegionAccessPolicy region_access_;     // who may own regions (region_owner.h)
  const PolicyFile* const policy_;             // null: every client may call every method
  FrameSocketCounters frame_socket_counters_;  // all 0 while --frame-socket is off
  OpenUploads open_uploads_;  // the caps and budget of uploads, and their idle watchdog
};

}  // namespace skinserve::server
