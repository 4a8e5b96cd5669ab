// SkinClient's animation uploads: a skeleton and its clips, each one unary call
// (docs/serving/animation.md#uploads).
#include "skinserve/client/skin_client.h"
#include "skinserve/wire/animation_conversions.h"

namespace skinserve::client {

Result<v1::SkeletonInfo> SkinClient::UploadSkeleton(const animation::Skeleton& skeleton) {
  v1::UploadSkeletonRequest request;
  wire::SkeletonToWire(skeleton, &request);
  grpc::ClientContext context;
  SetDeadline(&context, limits_.deadline);
  v1::SkeletonInfo info;
  if (grpc::Status s = stub_->UploadSkeleton(&context, request, &info); !s.ok()) {
    return wire::FromGrpc(s);
  }
  return info;
}

Result<v1::ClipInfo> SkinClient::UploadClip(const animation::RawClip& clip,
                                            const std::string& skeleton_id) {
  v1::UploadClipRequest request;
  wire::ClipToWire(clip, skeleton_id, &request);
  grpc::ClientContext context;
  SetDeadline(&context, limits_.upload_deadline);
  v1::ClipInfo info;
  if (grpc::Status s = stub_->UploadClip(&context, request, &info); !s.ok()) {
    return wire::FromGrpc(s);
  }
  return info;
}

Result<bool> SkinClient::DeleteClip(const std::string& clip_id) {
  v1::DeleteClipRequest request;
  request.set_clip_id(clip_id);
  grpc::ClientContext context;
  SetDeadline(&context, limits_.deadline);
  v1::DeleteClipResponse response;
  if (grpc::Status s = stub_->DeleteClip(&context, request, &response); !s.ok()) {
    return wire::FromGrpc(s);
  }
  return response.deleted();
}

}  // namespace skinserve::client
