#include "skinning_service.h"

#include "engine_messages.h"
#include "mesh_upload_reactor.h"
#include "skin_reactor.h"
#include "stream_skin_reactor.h"

namespace skinserve::server {
namespace {

grpc::ServerUnaryReactor* Done(grpc::CallbackServerContext* context, const Status& status) {
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  reactor->Finish(ToGrpc(status));
  return reactor;
}

const Status kWarmingUp = Unavailable("the server is starting: backends are being built");

}  // namespace

grpc::ServerReadReactor<v1::UploadMeshRequest>* SkinningService::UploadMesh(
    grpc::CallbackServerContext* context, v1::MeshInfo* response) {
  // The peer address ("ipv4:127.0.0.1:54321") names the client's connection.
  return new MeshUploadReactor(engine_.load(), &open_uploads_, context->peer(), response);
}

grpc::ServerUnaryReactor* SkinningService::GetMesh(grpc::CallbackServerContext* context,
                                                   const v1::GetMeshRequest* request,
                                                   v1::MeshInfo* response) {
  Engine* engine = engine_.load();
  if (engine == nullptr) return Done(context, kWarmingUp);
  auto info = engine->GetMesh(request->mesh_id());
  if (info.ok()) *response = ToWire(*info);
  return Done(context, info.status());
}

grpc::ServerUnaryReactor* SkinningService::DeleteMesh(grpc::CallbackServerContext* context,
                                                      const v1::DeleteMeshRequest* request,
                                                      v1::DeleteMeshResponse* response) {
  Engine* engine = engine_.load();
  if (engine == nullptr) return Done(context, kWarmingUp);
  response->set_deleted(engine->DeleteMesh(request->mesh_id()));
  return Done(context, Status::Ok());
}

grpc::ServerWriteReactor<grpc::ByteBuffer>* SkinningService::Skin(grpc::CallbackServerContext*,
                                                                  const grpc::ByteBuffer* request) {
  return new SkinReactor(engine_.load(), default_backend_, *request, &budget_);
}

grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* SkinningService::StreamSkin(
    grpc::CallbackServerContext*) {
  return new StreamSkinReactor(engine_.load(), default_backend_, stream_window_, &open_streams_,
                               &budget_);
}

grpc::ServerUnaryReactor* SkinningService::ListBackends(grpc::CallbackServerContext* context,
                                                        const v1::ListBackendsRequest*,
                                                        v1::ListBackendsResponse* response) {
  Engine* engine = engine_.load();
  if (engine == nullptr) return Done(context, kWarmingUp);
  for (const BackendInfo& info : engine->Backends()) *response->add_backends() = ToWire(info);
  response->set_default_backend(default_backend_);
  return Done(context, Status::Ok());
}

grpc::ServerUnaryReactor* SkinningService::GetServerStats(grpc::CallbackServerContext* context,
                                                          const v1::GetServerStatsRequest*,
                                                          v1::ServerStats* response) {
  Engine* engine = engine_.load();
  if (engine == nullptr) return Done(context, kWarmingUp);
  *response = ToWire(engine->Stats());
  response->set_open_streams(open_streams_.count());
  response->set_inflight_budget_bytes(budget_.limit());
  response->set_inflight_bytes(budget_.used());
  response->set_rejected_inflight_budget(budget_.refused());
  const UploadStats uploads = open_uploads_.Stats();
  response->set_upload_budget_bytes(uploads.budget_bytes);
  response->set_upload_bytes(uploads.bytes);
  response->set_open_uploads(uploads.open);
  response->set_rejected_uploads_max_uploads(uploads.refused_max_uploads);
  response->set_rejected_uploads_per_connection(uploads.refused_per_connection);
  response->set_rejected_uploads_budget(uploads.refused_budget);
  response->set_cancelled_uploads_idle(uploads.cancelled_idle);
  return Done(context, Status::Ok());
}

}  // namespace skinserve::server
