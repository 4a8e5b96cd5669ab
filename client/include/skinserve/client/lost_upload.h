// LostUpload: what a server's NOT_FOUND for a frame says it lacks, so that a client
// uploads that again (SkinClient::Reupload): the frame's mesh, or a skeleton or clip its
// pose names. The server names them in the message (docs/serving/animation.md#errors):
// "pose.skeleton_id 'S' is not stored", "pose.layers[i].clip_id 'C' is not stored"; any
// other NOT_FOUND for a frame is its mesh's.
#pragma once

#include <compare>
#include <string>

#include "skinserve/model/status.h"

namespace skinserve::client {

struct LostUpload {
  enum class Kind { kMesh, kSkeleton, kClip };
  Kind kind = Kind::kMesh;
  std::string id;
  auto operator<=>(const LostUpload&) const = default;
};

// What the NOT_FOUND `status` of a frame (or a tick's character) of mesh `mesh_id` names.
LostUpload LostUploadOf(const Status& status, const std::string& mesh_id);

}  // namespace skinserve::client
