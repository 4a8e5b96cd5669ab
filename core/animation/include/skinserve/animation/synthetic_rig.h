// A synthetic character for tests and benchmarks: a branching skeleton of any size with
// human-scale bones (5-25 cm), and a clip keyed the way exporters write them: translation,
// rotation and scale for every joint, most constant (bones keep their length), rotations
// swinging smoothly (LINEAR; every 7th joint CUBICSPLINE with its true tangents, every 11th
// STEP), the root walking forward, one joint's scale pulsing and one group of 4 morph
// weights. Deterministic for a seed.
#pragma once

#include <cstdint>

#include "skinserve/animation/raw_clip.h"
#include "skinserve/animation/skeleton.h"

namespace skinserve::animation {

struct SyntheticRig {
  Skeleton skeleton;  // every joint in the palette, inverse bind = inverse rest model
  RawClip clip;
};

SyntheticRig MakeSyntheticRig(uint32_t joints, uint32_t seed = 1, float seconds = 2.0f,
                              float keys_per_second = 30.0f);

}  // namespace skinserve::animation
