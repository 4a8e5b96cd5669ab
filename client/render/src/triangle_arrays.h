// The arrays every output of a frame shares (OBJ files, renders): checked once, the same way.
#pragma once

#include <cstdint>
#include <span>

#include "skinserve/model/status.h"

namespace skinserve::render {

// positions: 3 floats per vertex, all finite; normals: empty or as many as positions;
// indices: 3 per triangle, each below the vertex count. INVALID_ARGUMENT naming the array.
Status CheckTriangleArrays(std::span<const float> positions, std::span<const float> normals,
                           std::span<const uint32_t> indices);

}  // namespace skinserve::render
