// BlendingJob: layers of local poses mixed by weight. Normal layers' weights are
// normalised (divided by their sum); translations and scales are weighted means, rotations
// a normalised weighted sum with each quaternion's sign flipped onto the first layer's
// hemisphere (the shortest path: q and -q are one rotation). Additive layers then apply on
// top, each scaled by its weight: translation += w t, rotation = nlerp(1, q, w) * rotation,
// scale *= 1 + w (s - 1). Morph weights blend the same way (additive: += w x).
#pragma once

#include <cstdint>
#include <span>

#include "skinserve/animation/transform.h"
#include "skinserve/model/status.h"

namespace skinserve::animation {

inline constexpr uint32_t kMaxBlendLayers = 8;

struct BlendLayer {
  std::span<const Transform> pose;  // one per joint
  float weight = 1;                 // finite, >= 0
  bool additive = false;
  std::span<const float> morph_weights;  // empty, or the output's size
};

struct BlendingJob {
  std::span<const BlendLayer> layers;  // 1..kMaxBlendLayers, at least one normal layer
  std::span<Transform> output;         // one per joint
  std::span<float> morph_weights;      // empty, or every layer's morph weights' size

  // INVALID_ARGUMENT naming the layer and field: sizes, weights finite and >= 0, the
  // normal layers' weights summing to more than 0.
  Status Validate() const;
  Status Run() const;
};

// The morph weights' blend alone, by BlendingJob's rule (normal layers' weights divided by
// their sum, additive layers added times their weight), for a caller that needs them before
// the joints. A layer with empty morph_weights (a clip without weights tracks) contributes
// zeros, the mesh's rest shape, as a joint no track animates takes its rest pose.
// INVALID_ARGUMENT naming the layer: weights finite and >= 0 summing to more than 0 over
// the normal layers, morph_weights empty or the output's size.
Status BlendMorphWeights(std::span<const BlendLayer> layers, std::span<float> output);

}  // namespace skinserve::animation
