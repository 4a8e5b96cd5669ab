// What a load run sends: a mesh (synthetic, deterministic from a seed) and palettes that
// change every frame, plus the local Mesh used to check sampled answers.
#pragma once

#include <memory>
#include <vector>

#include "skinserve/core/mesh.h"

namespace skinserve::load {

inline constexpr int kDistinctPalettes = 32;

struct Workload {
  uint32_t vertices = 0;
  uint32_t bones = 0;
  uint32_t joints = 77;
  bool normals = false;
  std::shared_ptr<const MeshArrays> arrays;  // shared by every stream's client
  std::shared_ptr<const Mesh> mesh;          // for the float64 reference checks
  std::vector<std::vector<float>> palettes;  // frame f uses palettes[f % size]

  const std::vector<float>& Palette(uint64_t frame) const {
    return palettes[frame % palettes.size()];
  }
};

Workload MakeWorkload(uint32_t vertices, uint32_t bones, uint32_t joints, bool normals,
                      uint64_t seed);

}  // namespace skinserve::load
