// The float64 reference of a pose on the server (docs/serving/animation.md#pose): a clip's
// uploaded channels evaluated with glTF's formulas in double, written apart from
// core/animation's runtime (which samples the compact store in float32 and never appears
// here): STEP, LINEAR (rotations by slerp on the shortest path) and CUBICSPLINE (Hermite,
// rotations normalised), the skeleton's rest pose for joints no track animates, model
// matrices root down (T * R * S) and the palette.
#pragma once

#include <vector>

#include "skinserve/animation/raw_clip.h"
#include "skinserve/animation/skeleton.h"

namespace skinserve {

// `clip` on `skeleton` at `time` seconds, clamped to each track's first and last keys (a
// looped time is the caller's to wrap). Weights tracks are left out (the server does not
// apply them). 12 doubles a palette entry, row-major 3x4: model(palette_joints[p]) *
// inverse_bind[p].
std::vector<double> ReferencePosePalette(const animation::Skeleton& skeleton,
                                         const animation::RawClip& clip, double time);

}  // namespace skinserve
