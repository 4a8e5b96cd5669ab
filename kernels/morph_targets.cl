/* Morph targets (docs/serving/morph-targets.md) on the device, before skinning, with the
 * semantics of the CPU backends' morph stage (core/engine/src/backends/common/morph_stage.h): a
 * frame's rest arrays are the mesh's plus sum_t w_t * delta_t over its active targets, each
 * vertex's deltas added in the frame's order of its targets. These kernels write them into
 * the frame's morphed buffers, which the skinning kernels (skin_*, dqs_*) then read in place
 * of the mesh's rest arrays. A frame without an active target never runs them.
 *
 * The targets in the mesh's own layout (core/model/include/skinserve/model/mesh.h), on the
 * device once per mesh: target t's deltas are [offsets[t], offsets[t + 1]) of `indices`
 * (vertex indices, strictly ascending within a target), `position_deltas`, `normal_deltas`
 * and `tangent_deltas` (x y z per delta; tangents hold x y z w per vertex, and their w is
 * never morphed). Per frame only the active targets travel: `active`
 * holds `active_count` (target, weight) pairs laid out as the host's MorphWeight (uint32
 * target, float32 weight bits), read as uints (the host array is only 4-byte aligned).
 *
 * Shape: a work-item owns MORPH_VERTICES_PER_ITEM consecutive vertices. It copies their rest
 * values, then per active target skips the target when its vertex span misses the range
 * (a face rig's targets each move one region), else finds the target's first delta in the
 * range by binary search (the indices ascend) and adds deltas until the range ends. No two
 * items write one vertex, so no atomics (OpenCL 1.2 has no float atomics) and the sums are
 * deterministic. Work: the copy, the active deltas, and per item and active target one
 * search - which is what the item size trades: on PoCL (2 threads, 25k vertices, 4 of 64
 * targets active, each moving 10%) the kernel alone took ~190 us at 64 vertices an item
 * and ~50 us at 256. A one-target-per-launch scatter would need no search but pay a launch
 * per active target.
 */

#if !defined(MORPH_VERTICES_PER_ITEM)
#error "the host passes MORPH_VERTICES_PER_ITEM (kMorphVerticesPerItem in opencl_runtime.cpp)"
#endif

/* The first k in [first, end) with indices[k] >= vertex; end when there is none. */
static inline uint FirstDeltaFrom(const __global uint* restrict indices, uint first, uint end,
                                  const uint vertex) {
  while (first < end) {
    const uint middle = first + (end - first) / 2;
    if (indices[middle] < vertex) {
      first = middle + 1;
    } else {
      end = middle;
    }
  }
  return first;
}

/* Morphs this item's vertices; with_normals and with_tangents are constants of each kernel
 * below, so a frame without tangents runs the code it ran before tangents existed. */
static inline void MorphRange(const __global float* restrict positions,
                              const __global uint* restrict offsets,
                              const __global uint* restrict indices,
                              const __global float* restrict position_deltas,
                              const __global uint* restrict active, const uint active_count,
                              __global float* restrict morphed_positions, const uint vertex_count,
                              const __global float* restrict normals,
                              const __global float* restrict normal_deltas,
                              __global float* restrict morphed_normals, const int with_normals,
                              const __global float* restrict tangents,
                              const __global float* restrict tangent_deltas,
                              __global float* restrict morphed_tangents, const int with_tangents) {
  const uint begin = (uint)get_global_id(0) * MORPH_VERTICES_PER_ITEM;
  if (begin >= vertex_count) return;
  const uint end = min(begin + MORPH_VERTICES_PER_ITEM, vertex_count);
  for (uint i = 3 * begin; i < 3 * end; ++i) morphed_positions[i] = positions[i];
  if (with_normals) {
    for (uint i = 3 * begin; i < 3 * end; ++i) morphed_normals[i] = normals[i];
  }
  if (with_tangents) {
    for (uint i = 4 * begin; i < 4 * end; ++i) morphed_tangents[i] = tangents[i];
  }
  for (uint a = 0; a < active_count; ++a) {
    const float w = as_float(active[2 * a + 1]);
    if (w == 0.0f) continue;
    const uint target = active[2 * a];
    const uint first = offsets[target], last = offsets[target + 1];
    if (first == last || indices[first] >= end || indices[last - 1] < begin) continue;
    for (uint k = FirstDeltaFrom(indices, first, last, begin);
         k < last && indices[k] < end; ++k) {
      const uint v = indices[k];
      vstore3(vload3(v, morphed_positions) + w * vload3(k, position_deltas), v,
              morphed_positions);
      if (with_normals) {
        vstore3(vload3(v, morphed_normals) + w * vload3(k, normal_deltas), v, morphed_normals);
      }
      if (with_tangents) {
        /* xyz only: the tangent's w stays where it is (4 floats per vertex, 3 per delta). */
        __global float* tangent = morphed_tangents + 4 * v;
        vstore3(vload3(0, tangent) + w * vload3(k, tangent_deltas), 0, tangent);
      }
    }
  }
}

#define MORPH_ARGS                                                                          \
  const __global float *restrict positions, const __global uint *restrict offsets,         \
      const __global uint *restrict indices, const __global float *restrict position_deltas, \
      const __global uint *restrict active, const uint active_count,                       \
      __global float *restrict morphed_positions, const uint vertex_count
#define MORPH_NORMAL_ARGS                                                                   \
  const __global float *restrict normals, const __global float *restrict normal_deltas,    \
      __global float *restrict morphed_normals
#define MORPH_TANGENT_ARGS                                                                  \
  const __global float *restrict tangents, const __global float *restrict tangent_deltas,  \
      __global float *restrict morphed_tangents
#define MORPH_COMMON                                                                        \
  positions, offsets, indices, position_deltas, active, active_count, morphed_positions,   \
      vertex_count

/* Normals and tangents each morph where the frame asks for them and the targets move them
 * (tangent deltas come with or without normal deltas): one kernel per combination. */
__kernel void morph_positions(MORPH_ARGS) {
  MorphRange(MORPH_COMMON, 0, 0, 0, 0, 0, 0, 0, 0);
}

__kernel void morph_positions_normals(MORPH_ARGS, MORPH_NORMAL_ARGS) {
  MorphRange(MORPH_COMMON, normals, normal_deltas, morphed_normals, 1, 0, 0, 0, 0);
}

__kernel void morph_positions_tangents(MORPH_ARGS, MORPH_TANGENT_ARGS) {
  MorphRange(MORPH_COMMON, 0, 0, 0, 0, tangents, tangent_deltas, morphed_tangents, 1);
}

__kernel void morph_positions_normals_tangents(MORPH_ARGS, MORPH_NORMAL_ARGS,
                                               MORPH_TANGENT_ARGS) {
  MorphRange(MORPH_COMMON, normals, normal_deltas, morphed_normals, 1, tangents, tangent_deltas,
             morphed_tangents, 1);
}
