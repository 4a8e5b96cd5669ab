// Poses (SkinRequest.pose, docs/serving/animation.md): instead of a palette, a character
// names up to 8 layers of clips uploaded once (SkinClient::UploadSkeleton, UploadClip); the
// server samples, blends and turns them into the palette, then skins as usual.
#pragma once

#include <span>
#include <string>

#include "skinserve/v1/skinning.pb.h"

namespace skinserve::client {

struct PoseLayer {
  std::string clip_id;  // ClipInfo.clip_id
  float time = 0;       // seconds
  float weight = 1;     // >= 0; the layers that are not additive are normalised
  bool additive = false;
  bool loop = false;  // wrap past the clip's duration; false: clamp to its first/last keys
};

// Caller-owned, read when the request is written (as SkinOptions' morph weights are).
struct Pose {
  std::string skeleton_id;            // SkeletonInfo.skeleton_id
  std::span<const PoseLayer> layers;  // empty: no pose (the request carries a palette)
  bool empty() const { return layers.empty(); }
};

// Sets `request`'s pose to `pose`, or clears it when `pose` is empty.
void PoseToWire(const Pose& pose, v1::SkinRequest* request);

}  // namespace skinserve::client
