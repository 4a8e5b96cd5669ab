/* Linear blend skinning, the paper's equations 3 and 4:
 *   m = sum_i w_i * palette[joint_i]    (3x4 affine, row-major, 12 floats per joint)
 *   p' = m * (x, y, z, 1);  n' = normalize(upper 3x3 of m * n)
 * Layout: positions and normals xyz per vertex; joints (ushort) and weights vertex-major,
 * joints[v * B + i].
 *
 * Shape, chosen by measurement on PoCL 3.1's CPU device (LLVM 15):
 *  - One kernel per influence count B and per output set: skin_b1..skin_b8 and
 *    skin_normals_b1..skin_normals_b8. The blend loop has a constant trip count and is
 *    unrolled, and there is no branch on B or on normals per vertex (a uniform
 *    `if (with_normals)` alone cost ~10%).
 *  - Each work-item skins SKIN_VERTICES_PER_ITEM (4) consecutive vertices: more
 *    independent work per iteration of PoCL's work-item loop, and the four normals share
 *    one vector sqrt and division (scalar sqrt + div per normal cost more than the blend).
 *  - The blended matrix is a float8 (rows 0 and 1) and a float4 (row 2): two FMAs per
 *    influence. The transform itself is scalar FMAs: cheaper than dot() on float4, which
 *    needs shuffles and horizontal adds. Together: 17-40% less CPU time per frame than
 *    one vertex per item with float4 rows, dot() and a branch on normals.
 *  - Vectorising across work-items (PoCL's usual way) does not pay here: the palette
 *    lookup becomes a gather per matrix element; a scalar kernel that PoCL did vectorise
 *    so measured 3x slower at B = 4.
 *  - The last work-item clamps its vertex indices to V - 1 (recomputing, within itself,
 *    the last vertex) instead of branching per vertex; items past the end return.
 * On a GPU the same kernels run with a coalesced vertex order (SKIN_VERTEX below).
 * Normals use rsqrt (a sqrt and a true division on this device): full precision, never
 * native_ or half_ maths, so they match a float64 reference to 1e-5.
 */

/* The host passes -DSKIN_VERTICES_PER_ITEM, -DSKIN_ITEMS_PER_GROUP and -DSKIN_COALESCED;
 * skin_normals_b* is written out for four vertices per item. */
#if !defined(SKIN_VERTICES_PER_ITEM) || SKIN_VERTICES_PER_ITEM != 4
#error "SKIN_VERTICES_PER_ITEM must be 4 (kVerticesPerItem in core/src/backends/opencl_runtime.cpp)"
#endif
#if !defined(SKIN_ITEMS_PER_GROUP) || !defined(SKIN_COALESCED)
#error "the host passes SKIN_ITEMS_PER_GROUP and SKIN_COALESCED"
#endif

/* The k-th vertex of this work-item. On a CPU (SKIN_COALESCED 0) an item takes four
 * consecutive vertices, as measured above. On a GPU (1) a work-group of
 * SKIN_ITEMS_PER_GROUP items takes 4 * SKIN_ITEMS_PER_GROUP consecutive vertices and
 * item i takes i, i + SKIN_ITEMS_PER_GROUP, ...: neighbouring items (one warp) load and
 * store neighbouring vertices, so each access is one coalesced transaction. Both count
 * from the global id, so the host's global offset (a multiple of a group) starts a chunk
 * of a frame. */
#if SKIN_COALESCED
#define SKIN_VERTEX(k)                                                              \
  ((uint)(get_global_id(0) - get_local_id(0)) * SKIN_VERTICES_PER_ITEM +            \
   (uint)(k) * SKIN_ITEMS_PER_GROUP + (uint)get_local_id(0))
/* Several items may clamp to the last vertex: only the one that owns it stores it. */
#define SKIN_KEEP(raw, count) ((raw) < (count))
#else
#define SKIN_VERTEX(k) ((uint)get_global_id(0) * SKIN_VERTICES_PER_ITEM + (uint)(k))
/* Only this item recomputes the last vertex: storing it again costs no branch. */
#define SKIN_KEEP(raw, count) 1
#endif

/* Rows 0-1 and row 2 of one vertex's blended 3x4 matrix. */
typedef struct {
  float8 r01;
  float4 r2;
} Blended;

static inline Blended BlendPalette(const __global float* restrict palette,
                                   const __global ushort* restrict joints,
                                   const __global float* restrict weights, const uint v,
                                   const int influences) {
  Blended m = {(float8)(0.0f), (float4)(0.0f)};
#pragma unroll
  for (int i = 0; i < influences; ++i) {
    const float w = weights[v * influences + i];
    const __global float* joint = palette + 12 * (uint)joints[v * influences + i];
    m.r01 = fma((float8)(w), vload8(0, joint), m.r01);
    m.r2 = fma((float4)(w), vload4(2, joint), m.r2);
  }
  return m;
}

static inline void StorePosition(const Blended m, const __global float* restrict positions,
                                 __global float* restrict out_positions, const uint v) {
  const float x = positions[3 * v], y = positions[3 * v + 1], z = positions[3 * v + 2];
  out_positions[3 * v] = fma(m.r01.s0, x, fma(m.r01.s1, y, fma(m.r01.s2, z, m.r01.s3)));
  out_positions[3 * v + 1] = fma(m.r01.s4, x, fma(m.r01.s5, y, fma(m.r01.s6, z, m.r01.s7)));
  out_positions[3 * v + 2] = fma(m.r2.s0, x, fma(m.r2.s1, y, fma(m.r2.s2, z, m.r2.s3)));
}

/* The upper 3x3 of m times the normal, not yet renormalised. */
static inline float3 TransformNormal(const Blended m, const __global float* restrict normals,
                                     const uint v) {
  const float x = normals[3 * v], y = normals[3 * v + 1], z = normals[3 * v + 2];
  return (float3)(fma(m.r01.s0, x, fma(m.r01.s1, y, m.r01.s2 * z)),
                  fma(m.r01.s4, x, fma(m.r01.s5, y, m.r01.s6 * z)),
                  fma(m.r2.s0, x, fma(m.r2.s1, y, m.r2.s2 * z)));
}

static inline float SquaredLength(const float3 t) { return fma(t.x, t.x, fma(t.y, t.y, t.z * t.z)); }

#define SKIN_ARGS                                                                            \
  const __global float *restrict palette, const __global ushort *restrict joints,           \
      const __global float *restrict weights, const __global float *restrict positions,     \
      __global float *restrict out_positions, const uint vertex_count

#define DEFINE_SKIN_KERNELS(B)                                                               \
  __kernel void skin_b##B(SKIN_ARGS) {                                                       \
    if (SKIN_VERTEX(0) >= vertex_count) return;                                              \
    const uint last = vertex_count - 1;                                                      \
    _Pragma("unroll") for (uint k = 0; k < SKIN_VERTICES_PER_ITEM; ++k) {                    \
      const uint raw = SKIN_VERTEX(k), v = min(raw, last);                                   \
      const Blended m = BlendPalette(palette, joints, weights, v, B);                        \
      if (SKIN_KEEP(raw, vertex_count)) StorePosition(m, positions, out_positions, v);       \
    }                                                                                        \
  }                                                                                          \
  __kernel void skin_normals_b##B(SKIN_ARGS, const __global float* restrict normals,         \
                                  __global float* restrict out_normals) {                    \
    const uint r0 = SKIN_VERTEX(0), r1 = SKIN_VERTEX(1), r2 = SKIN_VERTEX(2),                \
               r3 = SKIN_VERTEX(3);                                                          \
    if (r0 >= vertex_count) return;                                                          \
    const uint last = vertex_count - 1;                                                      \
    const uint v0 = r0, v1 = min(r1, last), v2 = min(r2, last), v3 = min(r3, last);          \
    const Blended m0 = BlendPalette(palette, joints, weights, v0, B);                        \
    const Blended m1 = BlendPalette(palette, joints, weights, v1, B);                        \
    const Blended m2 = BlendPalette(palette, joints, weights, v2, B);                        \
    const Blended m3 = BlendPalette(palette, joints, weights, v3, B);                        \
    const float3 t0 = TransformNormal(m0, normals, v0), t1 = TransformNormal(m1, normals, v1), \
                 t2 = TransformNormal(m2, normals, v2), t3 = TransformNormal(m3, normals, v3); \
    const float4 inverse_length =                                                            \
        rsqrt((float4)(SquaredLength(t0), SquaredLength(t1), SquaredLength(t2),              \
                       SquaredLength(t3)));                                                  \
    StorePosition(m0, positions, out_positions, v0);                                         \
    vstore3(t0 * inverse_length.s0, v0, out_normals);                                        \
    if (SKIN_KEEP(r1, vertex_count)) {                                                       \
      StorePosition(m1, positions, out_positions, v1);                                       \
      vstore3(t1 * inverse_length.s1, v1, out_normals);                                      \
    }                                                                                        \
    if (SKIN_KEEP(r2, vertex_count)) {                                                       \
      StorePosition(m2, positions, out_positions, v2);                                       \
      vstore3(t2 * inverse_length.s2, v2, out_normals);                                      \
    }                                                                                        \
    if (SKIN_KEEP(r3, vertex_count)) {                                                       \
      StorePosition(m3, positions, out_positions, v3);                                       \
      vstore3(t3 * inverse_length.s3, v3, out_normals);                                      \
    }                                                                                        \
  }

DEFINE_SKIN_KERNELS(1)
DEFINE_SKIN_KERNELS(2)
DEFINE_SKIN_KERNELS(3)
DEFINE_SKIN_KERNELS(4)
DEFINE_SKIN_KERNELS(5)
DEFINE_SKIN_KERNELS(6)
DEFINE_SKIN_KERNELS(7)
DEFINE_SKIN_KERNELS(8)
