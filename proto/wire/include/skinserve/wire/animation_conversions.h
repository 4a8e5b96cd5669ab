// Skeletons and clips between the wire (UploadSkeletonRequest, UploadClipRequest) and the
// animation runtime's types, written once for the server and the clients. Only converts:
// malformed bytes and enum values are INVALID_ARGUMENT naming the field; what the values
// mean (hierarchy, key times, widths) is ValidateSkeleton's and BuildCompactClip's to check.
#pragma once

#include <string>

#include "skinserve/animation/raw_clip.h"
#include "skinserve/animation/skeleton.h"
#include "skinserve/model/status.h"
#include "skinserve/v1/skinning.pb.h"

namespace skinserve::wire {

// The most tracks one clip upload may hold (a 1024-joint skeleton's T, R and S, and morph
// weights groups), counted before anything is copied.
inline constexpr int kMaxClipTracks = 4096;

Result<animation::Skeleton> SkeletonFromWire(const v1::UploadSkeletonRequest& request);
void SkeletonToWire(const animation::Skeleton& skeleton, v1::UploadSkeletonRequest* request);

// A clip's duration 0 means its last key time.
Result<animation::RawClip> ClipFromWire(const v1::UploadClipRequest& request);
void ClipToWire(const animation::RawClip& clip, const std::string& skeleton_id,
                v1::UploadClipRequest* request);

}  // namespace skinserve::wire
