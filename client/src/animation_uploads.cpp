// SkinClient's animation uploads: a skeleton and its clips, each one unary call
// (docs/serving/animation.md#uploads).
#include <fmt/format.h>

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
  std::lock_guard lock(mutex_);
  auto& kept = skeletons_[info.skeleton_id()];
  if (kept == nullptr) kept = std::make_shared<const animation::Skeleton>(skeleton);
  return info;
}

Result<v1::ClipInfo> SkinClient::UploadClip(const animation::RawClip& clip,
                                            const std::string& skeleton_id, float max_error_mm) {
  v1::UploadClipRequest request;
  wire::ClipToWire(clip, skeleton_id, &request);
  request.set_max_error_mm(max_error_mm);
  grpc::ClientContext context;
  SetDeadline(&context, limits_.upload_deadline);
  v1::ClipInfo info;
  if (grpc::Status s = stub_->UploadClip(&context, request, &info); !s.ok()) {
    return wire::FromGrpc(s);
  }
  std::lock_guard lock(mutex_);
  UploadedClip& kept = clips_[info.clip_id()];
  if (kept.clip == nullptr) {
    kept = {std::make_shared<const animation::RawClip>(clip), skeleton_id, max_error_mm};
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
  std::lock_guard lock(mutex_);
  clips_.erase(clip_id);
  return response.deleted();
}

Status SkinClient::Reupload(const LostUpload& lost) {
  switch (lost.kind) {
    case LostUpload::Kind::kSkeleton:
      return ReuploadSkeleton(lost.id);
    case LostUpload::Kind::kClip:
      return ReuploadClip(lost.id);
    case LostUpload::Kind::kMesh:
      break;
  }
  return Reupload(lost.id);
}

Status SkinClient::ReuploadSkeleton(const std::string& skeleton_id) {
  std::shared_ptr<const animation::Skeleton> skeleton;
  std::vector<UploadedClip> clips;
  {
    std::lock_guard lock(mutex_);
    auto it = skeletons_.find(skeleton_id);
    if (it == skeletons_.end()) {
      return NotFound(fmt::format(
          "skeleton '{}' is not on the server and this client never uploaded it", skeleton_id));
    }
    skeleton = it->second;
    for (const auto& [id, kept] : clips_) {
      if (kept.skeleton_id == skeleton_id) clips.push_back(kept);
    }
  }
  if (auto info = UploadSkeleton(*skeleton); !info.ok()) return info.status();
  for (const UploadedClip& kept : clips) {
    if (auto info = UploadClip(*kept.clip, kept.skeleton_id, kept.max_error_mm); !info.ok())
      return info.status();
  }
  return Status::Ok();
}

Status SkinClient::ReuploadClip(const std::string& clip_id) {
  UploadedClip kept;
  {
    std::lock_guard lock(mutex_);
    auto it = clips_.find(clip_id);
    if (it == clips_.end()) {
      return NotFound(
          fmt::format("clip '{}' is not on the server and this client never uploaded it", clip_id));
    }
    kept = it->second;
  }
  auto info = UploadClip(*kept.clip, kept.skeleton_id, kept.max_error_mm);
  if (info.status().code() != StatusCode::kNotFound) return info.status();
  // The server lost the clip's skeleton too: that first (with its clips, this one among them).
  return ReuploadSkeleton(kept.skeleton_id);
}

}  // namespace skinserve::client
