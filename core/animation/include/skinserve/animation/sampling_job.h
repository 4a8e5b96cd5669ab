// SamplingJob: a clip's local pose at a time. Joints no track animates take the skeleton's
// rest pose; morph weights come out per weights track (CompactTrack::weight_offset).
// Validate() names the bad field; Run() validates first, so a bad job never writes.
#pragma once

#include <span>

#include "skinserve/animation/compact_clip.h"
#include "skinserve/animation/skeleton.h"
#include "skinserve/animation/transform.h"
#include "skinserve/model/status.h"

namespace skinserve::animation {

enum class TimeMode : uint8_t {
  kClamp,  // before 0: the first keys; after duration: the last
  kLoop,   // time modulo duration
};

struct SamplingJob {
  const Skeleton* skeleton = nullptr;
  const CompactClip* clip = nullptr;
  float time = 0;  // seconds, finite
  TimeMode mode = TimeMode::kClamp;
  std::span<Transform> output;     // skeleton->joint_count()
  std::span<float> morph_weights;  // clip->weight_count (may be empty when that is 0)

  Status Validate() const;
  Status Run() const;
};

}  // namespace skinserve::animation
