// The sampler's 4-wide path: four LINEAR smallest-three (16-bit or packed) rotation tracks of one
// clip (keyed at every clip time, so they share the segment) decoded and slerped side by side.
#pragma once

#include <span>

#include "sampling_plan.h"
#include "skinserve/animation/transform.h"

namespace skinserve::animation::detail {

// Where a group's two keys come from: decoded (and kept in `cache` when there is one),
// taken from `cache` as they are, or shifted (the cached next key is the new first one).
struct RotationKeys {
  enum State { kDecode, kCached, kShift };
  State state = kDecode;
  float* cache = nullptr;  // 32 floats a group: both keys' x y z w, 4 lanes each
};

// Every group of `groups` at key k, next key `next`, fraction u, into output[joint].rotation.
void SampleRotations4(const CompactClip& clip, std::span<const SamplingPlan::RotationGroup> groups,
                      uint32_t k, uint32_t next, float u, std::span<Transform> output,
                      RotationKeys keys);

}  // namespace skinserve::animation::detail
