// The animation RPCs of the Skinning service (UploadSkeleton, UploadClip, DeleteClip):
// wire messages into the engine's AnimationStore. Each is unary: a skeleton is at most
// ~90 KB and a clip's request at most gRPC's 4 MiB message, so neither needs chunks. The
// store builds and checks everything before it stores anything.
#include <fmt/format.h>

#include "rpc/server_messages.h"
#include "rpc/skinning_service.h"
#include "skinserve/wire/animation_conversions.h"

namespace skinserve::server {
namespace {

grpc::ServerUnaryReactor* Finished(grpc::CallbackServerContext* context, const Status& status) {
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  reactor->Finish(ToGrpc(status));
  return reactor;
}

const Status& WarmingUp() {
  static const Status status = Unavailable("the server is starting: backends are being built");
  return status;
}

}  // namespace

grpc::ServerUnaryReactor* SkinningService::UploadSkeleton(grpc::CallbackServerContext* context,
                                                          const v1::UploadSkeletonRequest* request,
                                                          v1::SkeletonInfo* response) {
  if (Status s = Authorize(*context, "UploadSkeleton"); !s.ok()) return Finished(context, s);
  Engine* engine = engine_.load();
  if (engine == nullptr) return Finished(context, WarmingUp());
  Result<animation::Skeleton> skeleton = wire::SkeletonFromWire(*request);
  if (!skeleton.ok()) return Finished(context, skeleton.status());
  Result<animation::SkeletonInfo> info = engine->animations().AddSkeleton(std::move(*skeleton));
  if (info.ok()) ToWire(*info, response);
  return Finished(context, info.status());
}

grpc::ServerUnaryReactor* SkinningService::UploadClip(grpc::CallbackServerContext* context,
                                                      const v1::UploadClipRequest* request,
                                                      v1::ClipInfo* response) {
  if (Status s = Authorize(*context, "UploadClip"); !s.ok()) return Finished(context, s);
  Engine* engine = engine_.load();
  if (engine == nullptr) return Finished(context, WarmingUp());
  Result<animation::RawClip> clip = wire::ClipFromWire(*request);
  if (!clip.ok()) return Finished(context, clip.status());
  // max_error_mm: the store checks it (INVALID_ARGUMENT naming it and its limits).
  Result<animation::ClipInfo> info = engine->animations().AddClip(
      *clip, request->skeleton_id(), {.max_error_mm = request->max_error_mm()});
  if (info.ok()) ToWire(*info, response);
  return Finished(context, info.status());
}

grpc::ServerUnaryReactor* SkinningService::DeleteClip(grpc::CallbackServerContext* context,
                                                      const v1::DeleteClipRequest* request,
                                                      v1::DeleteClipResponse* response) {
  if (Status s = Authorize(*context, "DeleteClip"); !s.ok()) return Finished(context, s);
  Engine* engine = engine_.load();
  if (engine == nullptr) return Finished(context, WarmingUp());
  response->set_deleted(engine->animations().DeleteClip(request->clip_id()));
  return Finished(context, Status::Ok());
}

}  // namespace skinserve::server
