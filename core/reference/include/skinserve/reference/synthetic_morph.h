// Synthetic morph targets for tests and benchmarks: sparse random targets added to a mesh's
// arrays, and a frame's sparse random weights. Deterministic from a seed on every platform.
#pragma once

#include <cstdint>
#include <vector>

#include "skinserve/model/mesh.h"
#include "skinserve/model/morph_targets.h"

namespace skinserve {

struct SyntheticMorphSpec {
  uint32_t targets = 64;
  double fraction = 0.1;  // each vertex is in each target with this probability
  bool normals = true;    // normal deltas too (when the mesh has normals)
  bool tangents = true;   // tangent deltas too (when the mesh has tangents)
  uint64_t seed = 1;
};

// Replaces `arrays`' morph targets with `spec.targets` random ones: each moves about
// fraction * vertex_count vertices spread over the whole mesh (no vertex order to exploit),
// by up to 0.1 per position component and, with normals, up to 0.3 per normal component
// (tangents: the same, drawn from a stream of their own so the other deltas stay the same).
void AddSyntheticMorphTargets(const SyntheticMorphSpec& spec, MeshArrays* arrays);

// `active` distinct targets of `target_count`, in random order, with weights in [-1.5, 1.5]
// (negative and beyond 1 included; never exactly 0). Deterministic from seed and frame.
std::vector<MorphWeight> MakeMorphWeights(uint32_t target_count, uint32_t active, uint64_t seed,
                                          uint64_t frame);

}  // namespace skinserve
