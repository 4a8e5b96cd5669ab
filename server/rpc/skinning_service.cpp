#include "rpc/skinning_service.h"

#include <fmt/format.h>

#include "rpc/mesh_upload_reactor.h"
#include "rpc/server_messages.h"
#include "rpc/skin_reactor.h"
#include "rpc/stream_skin_reactor.h"

namespace skinserve::server {
namespace {

grpc::ServerUnaryReactor* Done(grpc::CallbackServerContext* context, const Status& status) {
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  reactor->Finish(ToGrpc(status));
  return reactor;
}

// A call refused before it starts (the authorization policy): it finishes at once.
template <typename Reactor>
class Refused final : public Reactor {
 public:
  explicit Refused(const Status& status) { this->Finish(ToGrpc(status)); }
  void OnDone() override { delete this; }
};

const Status kWarmingUp = Unavailable("the server is starting: backends are being built");
const Status kNoSharedMemory =
    FailedPrecondition("this server's shared memory is off (--shm-dir is empty)");

}  // namespace

Status SkinningService::Authorize(const grpc::CallbackServerContext& context,
                                  const char* method) const {
  return server::Authorize(policy_, context, v1::Skinning::service_full_name(), method);
}

RegionCaller SkinningService::RegionCallerOf(const grpc::CallbackServerContext& context) const {
  if (regions_ == nullptr && gpu_regions_ == nullptr) return {};
  return {regions_, RegionOwnerOf(context, region_access_), gpu_regions_};
}

grpc::ServerReadReactor<v1::UploadMeshRequest>* SkinningService::UploadMesh(
    grpc::CallbackServerContext* context, v1::MeshInfo* response) {
  if (Status s = Authorize(*context, "UploadMesh"); !s.ok()) {
    return new Refused<grpc::ServerReadReactor<v1::UploadMeshRequest>>(s);
  }
  // The peer address ("ipv4:127.0.0.1:54321") names the client's connection.
  return new MeshUploadReactor(engine_.load(), &open_uploads_, context->peer(), response);
}

grpc::ServerUnaryReactor* SkinningService::GetMesh(grpc::CallbackServerContext* context,
                                                   const v1::GetMeshRequest* request,
                                                   v1::MeshInfo* response) {
  if (Status s = Authorize(*context, "GetMesh"); !s.ok()) return Done(context, s);
  Engine* engine = engine_.load();
  if (engine == nullptr) return Done(context, kWarmingUp);
  auto info = engine->GetMesh(request->mesh_id());
  if (info.ok()) *response = ToWire(*info);
  return Done(context, info.status());
}

grpc::ServerUnaryReactor* SkinningService::DeleteMesh(grpc::CallbackServerContext* context,
                                                      const v1::DeleteMeshRequest* request,
                                                      v1::DeleteMeshResponse* response) {
  if (Status s = Authorize(*context, "DeleteMesh"); !s.ok()) return Done(context, s);
  Engine* engine = engine_.load();
  if (engine == nullptr) return Done(context, kWarmingUp);
  response->set_deleted(engine->DeleteMesh(request->mesh_id()));
  return Done(context, Status::Ok());
}

grpc::ServerWriteReactor<grpc::ByteBuffer>* SkinningService::Skin(
    grpc::CallbackServerContext* context, const grpc::ByteBuffer* request) {
  if (Status s = Authorize(*context, "Skin"); !s.ok()) {
    return new Refused<grpc::ServerWriteReactor<grpc::ByteBuffer>>(s);
  }
  return new SkinReactor(engine_.load(), default_backend_, *request, &budget_,
                         RegionCallerOf(*context), request_limits_);
}

grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* SkinningService::StreamSkin(
    grpc::CallbackServerContext* context) {
  if (Status s = Authorize(*context, "StreamSkin"); !s.ok()) {
    return new Refused<grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>>(s);
  }
  return new StreamSkinReactor(engine_.load(), default_backend_, stream_window_, &open_streams_,
                               &budget_, RegionCallerOf(*context), request_limits_);
}

grpc::ServerUnaryReactor* SkinningService::ListBackends(grpc::CallbackServerContext* context,
                                                        const v1::ListBackendsRequest*,
                                                        v1::ListBackendsResponse* response) {
  if (Status s = Authorize(*context, "ListBackends"); !s.ok()) return Done(context, s);
  Engine* engine = engine_.load();
  if (engine == nullptr) return Done(context, kWarmingUp);
  for (const BackendInfo& info : engine->Backends()) *response->add_backends() = ToWire(info);
  response->set_default_backend(default_backend_);
  return Done(context, Status::Ok());
}

FrameSocketAccess SkinningService::FrameSocketAccessFor(const UnixPeerCredentials& peer) {
  FrameSocketAccess access;
  access.engine = engine_.load();
  access.default_backend = default_backend_;
  access.budget = &budget_;
  access.counters = &frame_socket_counters_;
  access.limits = WithMaxInstances(request_limits_, access.engine);
  if (regions_ != nullptr || gpu_regions_ != nullptr) {
    access.regions = {regions_, RegionOwner::OfUnixPeer(peer), gpu_regions_};
  }
  if (policy_ != nullptr) {
    access.allowed =
        policy_->Check(Peer{}, fmt::format("/{}/StreamSkin", v1::Skinning::service_full_name()));
  }
  return access;
}

ServerSnapshot SkinningService::Snapshot() const {
  ServerSnapshot s;
  s.version = SKINSERVE_VERSION;
  s.serving = serving_.load();
  s.open_streams = open_streams_.count();
  s.streams_ended_idle = open_streams_.ended_idle();
  s.frame_socket = {frame_socket_counters_.connections.load(),
                    frame_socket_counters_.refused.load(), frame_socket_counters_.requests.load()};
  s.inflight = {budget_.limit(), budget_.used(), budget_.refused()};
  s.uploads = open_uploads_.Stats();
  s.shared_memory = regions_ != nullptr;
  if (regions_ != nullptr) s.regions = regions_->Stats();
  if (const Engine* engine = engine_.load()) {
    s.engine = engine->Stats();
    const animation::AnimationStore& store = engine->animations();
    s.animations = {store.skeleton_count(), store.clip_count(), store.bytes(),
                    store.budget_bytes()};
  }
  if (const FrameMetrics* frames = FrameMetrics::Installed()) s.frames = frames->Snapshot();
  s.ticks = TickTotals();
  return s;
}

grpc::ServerUnaryReactor* SkinningService::GetServerStats(grpc::CallbackServerContext* context,
                                                          const v1::GetServerStatsRequest*,
                                                          v1::ServerStats* response) {
  if (Status s = Authorize(*context, "GetServerStats"); !s.ok()) return Done(context, s);
  if (engine_.load() == nullptr) return Done(context, kWarmingUp);
  *response = ToWire(Snapshot());
  return Done(context, Status::Ok());
}

grpc::ServerUnaryReactor* SkinningService::RegisterRegion(grpc::CallbackServerContext* context,
                                                          const v1::RegisterRegionRequest* request,
                                                          v1::RegionInfo* response) {
  if (Status s = Authorize(*context, "RegisterRegion"); !s.ok()) return Done(context, s);
  if (regions_ == nullptr) return Done(context, kNoSharedMemory);
  const Result<RegionOwner> owner = RegionOwnerOf(*context, region_access_);
  if (!owner.ok()) return Done(context, owner.status());
  Result<RegionInfo> info =
      regions_->Register(request->name(), request->key(), request->byte_size(), *owner);
  if (info.ok()) ToWire(*info, response);
  return Done(context, info.status());
}

grpc::ServerUnaryReactor* SkinningService::UnregisterRegion(
    grpc::CallbackServerContext* context, const v1::UnregisterRegionRequest* request,
    v1::UnregisterRegionResponse*) {
  if (Status s = Authorize(*context, "UnregisterRegion"); !s.ok()) return Done(context, s);
  if (regions_ == nullptr) return Done(context, kNoSharedMemory);
  const Result<RegionOwner> owner = RegionOwnerOf(*context, region_access_);
  if (!owner.ok()) return Done(context, owner.status());
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  // Answered once the last frame writing into the region is done and it is unmapped.
  Status status = regions_->Unregister(request->name(), *owner,
                                       [reactor] { reactor->Finish(grpc::Status::OK); });
  if (!status.ok()) reactor->Finish(ToGrpc(status));
  return reactor;
}

grpc::ServerUnaryReactor* SkinningService::ListRegions(grpc::CallbackServerContext* context,
                                                       const v1::ListRegionsRequest*,
                                                       v1::ListRegionsResponse* response) {
  if (Status s = Authorize(*context, "ListRegions"); !s.ok()) return Done(context, s);
  if (regions_ == nullptr) return Done(context, kNoSharedMemory);
  const Result<RegionOwner> owner = RegionOwnerOf(*context, region_access_);
  if (!owner.ok()) return Done(context, owner.status());
  for (const RegionInfo& info : regions_->List(*owner)) ToWire(info, response->add_regions());
  const RegionLimits& limits = regions_->limits();
  const RegionStats stats = regions_->Stats();
  response->set_shm_dir(limits.dir);
  response->set_budget_bytes(limits.budget_bytes);
  response->set_mapped_bytes(stats.mapped_bytes);
  response->set_idle_limit_seconds(limits.idle_seconds);
  response->set_max_regions(limits.max_regions);
  response->set_max_regions_per_connection(limits.max_per_connection);
  return Done(context, Status::Ok());
}

}  // namespace skinserve::server
