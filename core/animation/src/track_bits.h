// ChooseTrackBits: for a bound looser than the default, the fewest bits a component
// (kMinPackedBits..16) for each LINEAR or STEP joint track such that every joint stays
// within the clip's model-space bound (ModelErrorCheck), one track at a time, leaves first,
// binary search per track. At the default bound every track keeps 16 bits (the sampler's
// fastest keys).
#pragma once

#include <cstdint>
#include <vector>

#include "skinserve/animation/raw_clip.h"
#include "skinserve/animation/skeleton.h"

namespace skinserve::animation::detail {

// How the builder stores each raw track before bits are chosen.
enum class TrackKind : uint8_t { kAtRest, kConstant, kCandidate, kRange16 };

// Per raw track: its bits (16 for all but candidates it could lower).
std::vector<uint32_t> ChooseTrackBits(const RawClip& raw, const Skeleton& skeleton,
                                      const std::vector<TrackKind>& kinds, double max_error_mm);

}  // namespace skinserve::animation::detail
