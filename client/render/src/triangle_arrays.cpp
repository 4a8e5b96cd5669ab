#include "triangle_arrays.h"

#include <fmt/format.h>

#include <cmath>

namespace skinserve::render {

Status CheckTriangleArrays(std::span<const float> positions, std::span<const float> normals,
                           std::span<const uint32_t> indices) {
  if (positions.size() % 3 != 0) {
    return InvalidArgument(
        fmt::format("positions: {} floats is not 3 per vertex", positions.size()));
  }
  if (!normals.empty() && normals.size() != positions.size()) {
    return InvalidArgument(
        fmt::format("normals: {} floats, positions have {}", normals.size(), positions.size()));
  }
  if (indices.size() % 3 != 0) {
    return InvalidArgument(fmt::format("indices: {} is not 3 per triangle", indices.size()));
  }
  const uint64_t vertex_count = positions.size() / 3;
  for (std::size_t i = 0; i < indices.size(); ++i) {
    if (indices[i] >= vertex_count) {
      return InvalidArgument(fmt::format("indices[{}] = {} is not below vertex_count {}", i,
                                         indices[i], vertex_count));
    }
  }
  for (std::size_t i = 0; i < positions.size(); ++i) {
    if (!std::isfinite(positions[i])) {
      return InvalidArgument(fmt::format("positions[vertex {}] is not finite", i / 3));
    }
  }
  return Status::Ok();
}

}  // namespace skinserve::render
