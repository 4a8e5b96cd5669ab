// The sampler's 4-wide path: four LINEAR smallest-three rotation tracks of one clip (keyed
// at every clip time, so they share the segment) decoded and slerped side by side.
#pragma once

#include <span>

#include "sampling_plan.h"
#include "skinserve/animation/transform.h"

namespace skinserve::animation::detail {

// Every group of `plan` at key k, next key `next`, fraction u, into output[joint].rotation.
void SampleRotations4(const CompactClip& clip, const SamplingPlan& plan, uint32_t k, uint32_t next,
                      float u, std::span<Transform> output);

}  // namespace skinserve::animation::detail
