// Morph targets (blend shapes): a mesh's sparse per-target deltas and a frame's sparse target
// weights. A frame adds sum_t weight_t * delta_t to the rest positions (and normals) of the
// vertices each active target moves, before skinning; targets the frame leaves out weigh 0.
#pragma once

#include <cstdint>
#include <span>

#include "skinserve/model/status.h"

namespace skinserve {

// Limits that fit face rigs (hundreds of targets per mesh) and keep every sum finite.
inline constexpr uint32_t kMaxMorphTargets = 1024;  // targets per mesh
inline constexpr float kMaxMorphWeight = 100.0f;    // |weight| of one target in a frame
// A position delta's components are within kMorphDeltaRange times the mesh's extent (the
// diagonal of its rest box, at least 1): a delta beyond that is an exporter's error.
inline constexpr float kMorphDeltaRange = 16.0f;
// A normal delta's components are within this (deltas between unit normals lie within 2).
inline constexpr float kMaxMorphNormalDelta = 4.0f;

// One active target of a frame: its index in the mesh's targets and its weight (any sign,
// |weight| <= kMaxMorphWeight). A frame lists each target at most once, in any order.
struct MorphWeight {
  uint32_t target = 0;
  float weight = 0.0f;
};

// Checks a frame's weights against a mesh with `target_count` targets: every target below
// target_count, listed once, its weight finite and within kMaxMorphWeight. INVALID_ARGUMENT
// naming the field, the entry and the limit, e.g. "morph_weights[2]: target 70 is not below
// the mesh's morph_target_count 64". Allocates nothing.
Status ValidateMorphWeights(std::span<const MorphWeight> weights, uint32_t target_count);

// Whether any weight is non-zero: a frame without one skins the rest arrays as they are.
bool HasActiveMorph(std::span<const MorphWeight> weights);

}  // namespace skinserve
