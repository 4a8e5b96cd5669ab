// SamplingJob: a clip's local pose at a time. Joints no track animates take the skeleton's
// rest pose; morph weights come out per weights track (CompactTrack::weight_offset).
// Validate() names the bad field; Run() validates first, so a bad job never writes.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "skinserve/animation/compact_clip.h"
#include "skinserve/animation/skeleton.h"
#include "skinserve/animation/transform.h"
#include "skinserve/model/status.h"

namespace skinserve::animation {

enum class TimeMode : uint8_t {
  kClamp,  // before 0: the first keys; after duration: the last
  kLoop,   // time modulo duration
};

// What SamplingJob keeps between calls of one layer (one clip played by one character):
// the key segment it last sampled, so time moving forward finds its keys in O(1), and the
// rotation keys it decoded for it, decoded again only when the segment moves on (then the
// old next key becomes the new first one). Optional: a job without one searches and
// decodes every call. Any time, any clip, in any order stays correct: a context notices
// another clip or a jump and starts again. One context per concurrent job.
struct SamplingContext {
  // Forgets what it holds (not needed for correctness; frees the clip's plan early).
  void Reset();

  // SamplingJob's bookkeeping, read and written by it alone.
  std::shared_ptr<const SamplingPlan> plan;  // whose keys these are (held: never reused)
  uint32_t k = 0, next = 0;                  // the segment they belong to
  bool valid = false;
  std::vector<float> keys;  // per rotation group: both keys, 4 lanes x 4 components each
};

struct SamplingJob {
  const Skeleton* skeleton = nullptr;
  const CompactClip* clip = nullptr;
  float time = 0;  // seconds, finite
  TimeMode mode = TimeMode::kClamp;
  std::span<Transform> output;         // skeleton->joint_count()
  std::span<float> morph_weights;      // clip->weight_count (may be empty when that is 0)
  SamplingContext* context = nullptr;  // optional: the same layer's previous calls

  Status Validate() const;
  Status Run() const;
};

// A clip's morph weights alone at a time (its weights tracks, as SamplingJob samples them):
// for a caller that needs them before the joints (the server, while preparing a frame).
struct MorphSamplingJob {
  const CompactClip* clip = nullptr;
  float time = 0;  // seconds, finite
  TimeMode mode = TimeMode::kClamp;
  std::span<float> morph_weights;  // clip->weight_count

  Status Run() const;
};

}  // namespace skinserve::animation
