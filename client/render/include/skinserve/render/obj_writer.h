// OBJ (Wavefront) output of one deformed frame: the mesh format every viewer opens.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "skinserve/core/status.h"

namespace skinserve::render {

// Writes `v x y z` per vertex, `vn x y z` per vertex when `normals` is not empty, and one
// `f` per triangle of `indices` (1-based; `f a//a b//b c//c` with normals). Floats are
// written in their shortest form that reads back to the same float.
// INVALID_ARGUMENT when the arrays disagree (positions not 3 per vertex, normals not the
// positions' size, indices not 3 per triangle or not below the vertex count); INTERNAL
// naming the path and the system's reason when the file cannot be written.
Status WriteObj(const std::string& path, std::span<const float> positions,
                std::span<const float> normals, std::span<const uint32_t> indices);

// "<dir>/frame_0007.<extension>": the name of frame `frame` in an output directory.
std::string FrameFileName(const std::string& dir, uint64_t frame, const std::string& extension);

}  // namespace skinserve::render
