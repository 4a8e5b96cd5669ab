// Axis-aligned bounding box of a frame's positions: what the camera frames.
#pragma once

#include <span>

#include <glm/vec3.hpp>

#include "skinserve/model/status.h"

namespace skinserve::render {

struct Bounds {
  glm::vec3 min{0.0f};
  glm::vec3 max{0.0f};
};

// The box around `positions` (x y z per vertex). INVALID_ARGUMENT when there is no vertex,
// the size is not 3 per vertex, or a coordinate is not finite (naming the vertex).
Result<Bounds> BoundsOf(std::span<const float> positions);

}  // namespace skinserve::render
