// The morph stage's inner loop (morph_stage.cpp): one active target's sparse deltas
// scatter-added into a chunk of the thread's morphed rest arrays. Written with Highway
// (morph_delta_kernel.cpp) so that where the CPU has masked stores (AVX-512) a vertex's three
// floats are one load, one multiply-add and one store instead of three each: the scalar loop
// was bound by its stores.
#pragma once

#include <cstddef>
#include <cstdint>

namespace skinserve {

struct MorphDeltaRun {
  const uint32_t* next;  // the target's next vertex index at or above the chunk's first, ascending
  const uint32_t* end;   // the target's last index + 1
  std::size_t first;     // the chunk's first vertex: index 0 of the arrays below
  std::size_t last;      // the chunk's end: indices from here on are left for the next chunk
  float weight;          // the target's weight this frame
  // The deltas of *next: 3 floats each; normals/tangents null when the walk does not morph them.
  const float* position_deltas;
  const float* normal_deltas;
  const float* tangent_deltas;
  // The chunk's morphed rest arrays from its first vertex (3, 3 and 4 floats per vertex).
  float* positions;
  float* normals;
  float* tangents;
};

// Adds run.weight x delta to each vertex of [next, first index >= last) and returns that
// first index (run.end when the target has no vertex left).
const uint32_t* AddMorphDeltas(const MorphDeltaRun& run);

}  // namespace skinserve
