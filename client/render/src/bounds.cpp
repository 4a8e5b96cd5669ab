#include "skinserve/render/bounds.h"

#include <fmt/format.h>

#include <cmath>

#include <glm/common.hpp>

namespace skinserve::render {

Result<Bounds> BoundsOf(std::span<const float> positions) {
  if (positions.empty() || positions.size() % 3 != 0) {
    return InvalidArgument(fmt::format(
        "positions: {} floats is not 3 per vertex, at least one vertex", positions.size()));
  }
  Bounds b{glm::vec3(positions[0], positions[1], positions[2]),
           glm::vec3(positions[0], positions[1], positions[2])};
  for (std::size_t i = 0; i < positions.size(); i += 3) {
    const glm::vec3 p(positions[i], positions[i + 1], positions[i + 2]);
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      return InvalidArgument(fmt::format("positions[vertex {}] is not finite", i / 3));
    }
    b.min = glm::min(b.min, p);
    b.max = glm::max(b.max, p);
  }
  return b;
}

}  // namespace skinserve::render
