// OBJ (Wavefront) output of one deformed frame: the mesh format every viewer opens.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "skinserve/model/status.h"

namespace skinserve::render {

// Triangles indices[first_index, first_index + index_count) of an ObjMesh, written under
// `g name` (a viewer lists them as separate objects).
struct ObjGroup {
  std::string name;
  std::size_t first_index = 0;
  std::size_t index_count = 0;
};

// One mesh of the frame: x y z per vertex, normals empty or x y z per vertex, triangles
// into this mesh's own vertices, and its groups (none: every triangle, ungrouped).
struct ObjMesh {
  std::span<const float> positions;
  std::span<const float> normals;
  std::span<const uint32_t> indices;
  std::vector<ObjGroup> groups;
};

// Writes every mesh's `v x y z` lines, then `vn x y z` for those with normals, then each
// group's faces (1-based, renumbered past the meshes before it; `f a//n b//n c//n` for a
// mesh with normals). Floats are written in their shortest form that reads back to the
// same float. INVALID_ARGUMENT when the arrays disagree (positions not 3 per vertex, normals
// not the positions' size, indices not 3 per triangle or not below the vertex count, a
// group outside the indices or not whole triangles), naming the mesh when there are several;
// INTERNAL naming the path and the system's reason when the file cannot be written.
Status WriteObj(const std::string& path, std::span<const ObjMesh> meshes);

// One mesh, no groups.
Status WriteObj(const std::string& path, std::span<const float> positions,
                std::span<const float> normals, std::span<const uint32_t> indices);

// "<dir>/frame_0007.<extension>": the name of frame `frame` in an output directory.
std::string FrameFileName(const std::string& dir, uint64_t frame, const std::string& extension);

}  // namespace skinserve::render
