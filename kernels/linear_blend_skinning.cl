/* Linear blend skinning, the paper's equations 3 and 4:
 *   m = sum_i w_i * palette[joint_i]    (3x4 affine, row-major, 12 floats per joint)
 *   p' = m * (x, y, z, 1);  n' = normalize(upper 3x3 of m * n)
 *   t'.xyz = normalize(upper 3x3 of m * t.xyz), t'.w = t.w  (tangents, as the CPU loops)
 * Layout: positions and normals xyz per vertex, tangents xyzw; joints (ushort) and weights
 * vertex-major, joints[v * B + i].
 *
 * Shape, chosen by measurement on PoCL 3.1's CPU device (LLVM 15):
 *  - One kernel per influence count B and per output set: skin_b1..skin_b8,
 *    skin_normals_b1..skin_normals_b8 and skin_tangents_b1..skin_tangents_b8 (normals and
 *    tangents: a frame with tangents always has normals). The blend loop has a constant
 *    trip count and is unrolled, and there is no branch on B, on normals or on tangents
 *    per vertex (a uniform `if (with_normals)` alone cost ~10%): a frame without tangents
 *    runs the very kernels it ran before tangents existed.
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
 * On a GPU the same kernels run with a coalesced vertex order (SKIN_VERTEX below), and
 * with SKIN_LOCAL_PALETTE the *_local_* kernels stage the palette in local memory first
 * (below). Palette records, joints and weights are read as aligned vectors (float4 rows,
 * LoadInfluences): vload8/vload4 on a float pointer promise only a float's alignment, and
 * NVIDIA's compiler made them scalar loads, which halved the kernel's speed on an H200
 * (docs/backends/opencl.md#aligned-loads).
 * Normals use rsqrt (a sqrt and a true division on this device): full precision, never
 * native_ or half_ maths, so they match a float64 reference to 1e-5.
 */

/* The host passes -DSKIN_VERTICES_PER_ITEM, -DSKIN_ITEMS_PER_GROUP, -DSKIN_COALESCED and
 * -DSKIN_LOCAL_PALETTE (0, or 1 with -DSKIN_LOCAL_TILES); skin_normals_b* and
 * skin_tangents_b* are written out for four vertices per item. */
#if !defined(SKIN_VERTICES_PER_ITEM) || SKIN_VERTICES_PER_ITEM != 4
#error "SKIN_VERTICES_PER_ITEM must be 4 (kVerticesPerItem in core/src/backends/opencl_runtime.cpp)"
#endif
#if !defined(SKIN_ITEMS_PER_GROUP) || !defined(SKIN_COALESCED) || !defined(SKIN_LOCAL_PALETTE)
#error "the host passes SKIN_ITEMS_PER_GROUP, SKIN_COALESCED and SKIN_LOCAL_PALETTE"
#endif
#if SKIN_LOCAL_PALETTE && (!SKIN_COALESCED || !defined(SKIN_LOCAL_TILES) || SKIN_LOCAL_TILES < 1)
#error "SKIN_LOCAL_PALETTE needs SKIN_COALESCED 1 and SKIN_LOCAL_TILES >= 1"
#endif

/* The k-th vertex of this work-item. On a CPU (SKIN_COALESCED 0) an item takes four
 * consecutive vertices, as measured above. On a GPU (1) a work-group of
 * SKIN_ITEMS_PER_GROUP items takes 4 * SKIN_ITEMS_PER_GROUP consecutive vertices and
 * item i takes i, i + SKIN_ITEMS_PER_GROUP, ...: neighbouring items (one warp) load and
 * store neighbouring vertices, so each access is one coalesced transaction. Both count
 * from the global id, so the host's global offset (a multiple of a group) starts a chunk
 * of a frame. */
#if SKIN_COALESCED
#define SKIN_VERTEX(k)                                                                     \
  ((uint)(get_global_id(0) - get_local_id(0)) * SKIN_VERTICES_PER_ITEM +                   \
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

/* Vertex v's B joints and weights, as whole vectors where the layout allows (B a multiple
 * of 4 or of 2: a vertex's joints[v * B ..] and weights[v * B ..] then start on a vector
 * boundary, and the buffers' bases are aligned far beyond that): on a GPU one 16-byte load
 * instead of four 4-byte ones (vload4 on a float pointer promises no more than a float's
 * alignment, so it compiles to scalar loads). B is a constant: one branch survives. */
static inline void LoadInfluences(const __global ushort* restrict joints,
                                  const __global float* restrict weights, const uint v,
                                  const int influences, uint* joint, float* weight) {
  if (influences % 4 == 0) {
    for (int g = 0; g < influences / 4; ++g) {
      const uint at = v * (uint)(influences / 4) + (uint)g;
      const ushort4 j = ((const __global ushort4*)joints)[at];
      const float4 w = ((const __global float4*)weights)[at];
      joint[4 * g] = j.s0, joint[4 * g + 1] = j.s1;
      joint[4 * g + 2] = j.s2, joint[4 * g + 3] = j.s3;
      weight[4 * g] = w.s0, weight[4 * g + 1] = w.s1;
      weight[4 * g + 2] = w.s2, weight[4 * g + 3] = w.s3;
    }
  } else if (influences % 2 == 0) {
    for (int g = 0; g < influences / 2; ++g) {
      const uint at = v * (uint)(influences / 2) + (uint)g;
      const ushort2 j = ((const __global ushort2*)joints)[at];
      const float2 w = ((const __global float2*)weights)[at];
      joint[2 * g] = j.s0, joint[2 * g + 1] = j.s1;
      weight[2 * g] = w.s0, weight[2 * g + 1] = w.s1;
    }
  } else {
    for (int i = 0; i < influences; ++i) {
      joint[i] = joints[v * influences + i];
      weight[i] = weights[v * influences + i];
    }
  }
}

/* A joint's 12 floats as three aligned float4 loads (the palette's base is aligned: a
 * buffer's, or a __local float4 array's). */
#define SKIN_JOINT_ROWS01(SPACE, palette, j) \
  (float8)(((const SPACE float4*)(palette))[3 * (j)], ((const SPACE float4*)(palette))[3 * (j) + 1])
#define SKIN_JOINT_ROW2(SPACE, palette, j) (((const SPACE float4*)(palette))[3 * (j) + 2])

/* The blend from a palette in either address space: __global (every kernel but the
 * *_local_* ones) or __local (those, after StagePalette). */
#define DEFINE_BLEND_PALETTE(NAME, SPACE)                                                  \
  static inline Blended NAME(const SPACE void* restrict palette,                           \
                             const __global ushort* restrict joints,                       \
                             const __global float* restrict weights, const uint v,         \
                             const int influences) {                                       \
    uint joint[8];                                                                         \
    float weight[8];                                                                       \
    LoadInfluences(joints, weights, v, influences, joint, weight);                         \
    Blended m = {(float8)(0.0f), (float4)(0.0f)};                                          \
    _Pragma("unroll") for (int i = 0; i < influences; ++i) {                               \
      m.r01 = fma((float8)(weight[i]), SKIN_JOINT_ROWS01(SPACE, palette, joint[i]), m.r01); \
      m.r2 = fma((float4)(weight[i]), SKIN_JOINT_ROW2(SPACE, palette, joint[i]), m.r2);    \
    }                                                                                      \
    return m;                                                                              \
  }
DEFINE_BLEND_PALETTE(BlendPalette, __global)

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

/* The upper 3x3 of m times the tangent's xyz (4 floats per vertex), not yet renormalised. */
static inline float3 TransformTangent(const Blended m, const __global float* restrict tangents,
                                      const uint v) {
  const float x = tangents[4 * v], y = tangents[4 * v + 1], z = tangents[4 * v + 2];
  return (float3)(fma(m.r01.s0, x, fma(m.r01.s1, y, m.r01.s2 * z)),
                  fma(m.r01.s4, x, fma(m.r01.s5, y, m.r01.s6 * z)),
                  fma(m.r2.s0, x, fma(m.r2.s1, y, m.r2.s2 * z)));
}

/* The skinned tangent: xyz already renormalised, w the rest tangent's (never transformed). */
static inline void StoreTangent(const float3 xyz, const __global float* restrict tangents,
                                __global float* restrict out_tangents, const uint v) {
  vstore4((float4)(xyz, tangents[4 * v + 3]), v, out_tangents);
}

#define SKIN_ARGS                                                                          \
  const __global float *restrict palette, const __global ushort *restrict joints,          \
      const __global float *restrict weights, const __global float *restrict positions,    \
      __global float *restrict out_positions, const uint vertex_count

/* The bodies of skin_b* and skin_normals_b*: BLEND reads PALETTE, VERTEX(k) is the k-th
 * vertex of this work-item. */
#define SKIN_POSITIONS_BODY(B, BLEND, PALETTE, VERTEX)                                     \
  if (VERTEX(0) >= vertex_count) return;                                                   \
  const uint last = vertex_count - 1;                                                      \
  _Pragma("unroll") for (uint k = 0; k < SKIN_VERTICES_PER_ITEM; ++k) {                    \
    const uint raw = VERTEX(k), v = min(raw, last);                                        \
    const Blended m = BLEND(PALETTE, joints, weights, v, B);                               \
    if (SKIN_KEEP(raw, vertex_count)) StorePosition(m, positions, out_positions, v);       \
  }

/* TANGENTS_PREPARE and TANGENT(k, v) (a statement with its own semicolon) add the tangents
 * to skin_normals_b*'s body: the four tangents transformed and sharing one vector sqrt and
 * division, as the normals do (SKIN_TANGENTS_*), or nothing at all (SKIN_NO_TANGENTS_*:
 * skin_normals_b* preprocesses to the very text it had before tangents existed). */
#define SKIN_NO_TANGENTS_PREPARE
#define SKIN_NO_TANGENT(k, v)
#define SKIN_TANGENTS_PREPARE                                                                 \
  const float3 s0 = TransformTangent(m0, tangents, v0), s1 = TransformTangent(m1, tangents, v1), \
               s2 = TransformTangent(m2, tangents, v2), s3 = TransformTangent(m3, tangents, v3); \
  const float4 tangent_inverse_length =                                                       \
      rsqrt((float4)(SquaredLength(s0), SquaredLength(s1), SquaredLength(s2),                 \
                     SquaredLength(s3)));
#define SKIN_TANGENT(k, v) \
  StoreTangent(s##k * tangent_inverse_length.s##k, tangents, out_tangents, v);

#define SKIN_NORMALS_BODY(B, BLEND, PALETTE, VERTEX, TANGENTS_PREPARE, TANGENT)               \
  const uint r0 = VERTEX(0), r1 = VERTEX(1), r2 = VERTEX(2), r3 = VERTEX(3);                  \
  if (r0 >= vertex_count) return;                                                             \
  const uint last = vertex_count - 1;                                                         \
  const uint v0 = r0, v1 = min(r1, last), v2 = min(r2, last), v3 = min(r3, last);             \
  const Blended m0 = BLEND(PALETTE, joints, weights, v0, B);                                  \
  const Blended m1 = BLEND(PALETTE, joints, weights, v1, B);                                  \
  const Blended m2 = BLEND(PALETTE, joints, weights, v2, B);                                  \
  const Blended m3 = BLEND(PALETTE, joints, weights, v3, B);                                  \
  const float3 t0 = TransformNormal(m0, normals, v0), t1 = TransformNormal(m1, normals, v1),  \
               t2 = TransformNormal(m2, normals, v2), t3 = TransformNormal(m3, normals, v3);  \
  const float4 inverse_length =                                                               \
      rsqrt((float4)(SquaredLength(t0), SquaredLength(t1), SquaredLength(t2),                 \
                     SquaredLength(t3)));                                                     \
  TANGENTS_PREPARE                                                                            \
  StorePosition(m0, positions, out_positions, v0);                                            \
  vstore3(t0 * inverse_length.s0, v0, out_normals);                                           \
  TANGENT(0, v0)                                                                              \
  if (SKIN_KEEP(r1, vertex_count)) {                                                          \
    StorePosition(m1, positions, out_positions, v1);                                          \
    vstore3(t1 * inverse_length.s1, v1, out_normals);                                         \
    TANGENT(1, v1)                                                                            \
  }                                                                                           \
  if (SKIN_KEEP(r2, vertex_count)) {                                                          \
    StorePosition(m2, positions, out_positions, v2);                                          \
    vstore3(t2 * inverse_length.s2, v2, out_normals);                                         \
    TANGENT(2, v2)                                                                            \
  }                                                                                           \
  if (SKIN_KEEP(r3, vertex_count)) {                                                          \
    StorePosition(m3, positions, out_positions, v3);                                          \
    vstore3(t3 * inverse_length.s3, v3, out_normals);                                         \
    TANGENT(3, v3)                                                                            \
  }

/* The normals' and the tangents' arguments, after SKIN_ARGS. */
#define SKIN_NORMAL_ARGS \
  const __global float *restrict normals, __global float *restrict out_normals
#define SKIN_TANGENT_ARGS \
  SKIN_NORMAL_ARGS, const __global float *restrict tangents, __global float *restrict out_tangents

#define DEFINE_SKIN_KERNELS(B)                                                             \
  __kernel void skin_b##B(SKIN_ARGS) {                                                     \
    SKIN_POSITIONS_BODY(B, BlendPalette, palette, SKIN_VERTEX)                             \
  }                                                                                        \
  __kernel void skin_normals_b##B(SKIN_ARGS, SKIN_NORMAL_ARGS) {                           \
    SKIN_NORMALS_BODY(B, BlendPalette, palette, SKIN_VERTEX, SKIN_NO_TANGENTS_PREPARE,     \
                      SKIN_NO_TANGENT)                                                     \
  }                                                                                        \
  __kernel void skin_tangents_b##B(SKIN_ARGS, SKIN_TANGENT_ARGS) {                         \
    SKIN_NORMALS_BODY(B, BlendPalette, palette, SKIN_VERTEX, SKIN_TANGENTS_PREPARE,        \
                      SKIN_TANGENT)                                                        \
  }

#if SKIN_LOCAL_PALETTE
/* The palette in work-group local memory (a GPU's shared memory), for devices where the
 * per-vertex gathers of 48-byte matrices from global memory cost more than one coalesced
 * copy of the whole palette per work-group: the group's items copy the frame's
 * `palette_floats` floats into `staged` (sized by the host to exactly that, which fits
 * the device's CL_DEVICE_LOCAL_MEM_SIZE; else the host runs the global kernels above),
 * wait at the barrier, and then blend from local memory. A group skins
 * SKIN_LOCAL_TILES tiles of SKIN_VERTICES_PER_ITEM * SKIN_ITEMS_PER_GROUP consecutive
 * vertices, each tile in the coalesced order of SKIN_VERTEX, so one copy serves
 * SKIN_LOCAL_TILES tiles. Every item reaches the barrier before any returns. */
DEFINE_BLEND_PALETTE(BlendLocalPalette, __local)

static inline void StagePalette(const __global float* restrict palette,
                                __local float4* restrict staged, const uint palette_floats) {
  /* palette_floats is a multiple of 4 (12 or 8 per joint). */
  for (uint i = (uint)get_local_id(0); i < palette_floats / 4; i += (uint)get_local_size(0)) {
    staged[i] = ((const __global float4*)palette)[i];
  }
  barrier(CLK_LOCAL_MEM_FENCE);
}

/* The first vertex of tile `tile` of this work-group; the global offset (a multiple of a
 * group, in items) starts a chunk of a frame, as for SKIN_VERTEX. */
#define SKIN_TILE_BASE(tile)                                                               \
  (((uint)get_global_offset(0) + (uint)get_group_id(0) * SKIN_LOCAL_TILES *                \
                                     (uint)get_local_size(0)) * SKIN_VERTICES_PER_ITEM +   \
   (uint)(tile) * (SKIN_VERTICES_PER_ITEM * SKIN_ITEMS_PER_GROUP))
#define SKIN_TILE_VERTEX(k) (tile_base + (uint)(k) * SKIN_ITEMS_PER_GROUP + (uint)get_local_id(0))
/* float4: local memory aligned for the palette's vector loads. */
#define SKIN_LOCAL_ARGS __local float4 *restrict staged, const uint palette_floats

/* Tiles ascend: an item whose first vertex of a tile is past the end returns (the body's
 * `return`), and so would it for every later tile. */
#define DEFINE_LOCAL_SKIN_KERNELS(B)                                                        \
  __kernel void skin_local_b##B(SKIN_ARGS, SKIN_LOCAL_ARGS) {                               \
    StagePalette(palette, staged, palette_floats);                                          \
    for (uint tile = 0; tile < SKIN_LOCAL_TILES; ++tile) {                                  \
      const uint tile_base = SKIN_TILE_BASE(tile);                                          \
      SKIN_POSITIONS_BODY(B, BlendLocalPalette, staged, SKIN_TILE_VERTEX)                   \
    }                                                                                       \
  }                                                                                         \
  __kernel void skin_normals_local_b##B(SKIN_ARGS, SKIN_NORMAL_ARGS, SKIN_LOCAL_ARGS) {     \
    StagePalette(palette, staged, palette_floats);                                          \
    for (uint tile = 0; tile < SKIN_LOCAL_TILES; ++tile) {                                  \
      const uint tile_base = SKIN_TILE_BASE(tile);                                          \
      SKIN_NORMALS_BODY(B, BlendLocalPalette, staged, SKIN_TILE_VERTEX,                     \
                        SKIN_NO_TANGENTS_PREPARE, SKIN_NO_TANGENT)                          \
    }                                                                                       \
  }                                                                                         \
  __kernel void skin_tangents_local_b##B(SKIN_ARGS, SKIN_TANGENT_ARGS, SKIN_LOCAL_ARGS) {   \
    StagePalette(palette, staged, palette_floats);                                          \
    for (uint tile = 0; tile < SKIN_LOCAL_TILES; ++tile) {                                  \
      const uint tile_base = SKIN_TILE_BASE(tile);                                          \
      SKIN_NORMALS_BODY(B, BlendLocalPalette, staged, SKIN_TILE_VERTEX,                     \
                        SKIN_TANGENTS_PREPARE, SKIN_TANGENT)                                \
    }                                                                                       \
  }
#else
#define DEFINE_LOCAL_SKIN_KERNELS(B)
#endif

DEFINE_SKIN_KERNELS(1)
DEFINE_SKIN_KERNELS(2)
DEFINE_SKIN_KERNELS(3)
DEFINE_SKIN_KERNELS(4)
DEFINE_SKIN_KERNELS(5)
DEFINE_SKIN_KERNELS(6)
DEFINE_SKIN_KERNELS(7)
DEFINE_SKIN_KERNELS(8)
DEFINE_LOCAL_SKIN_KERNELS(1)
DEFINE_LOCAL_SKIN_KERNELS(2)
DEFINE_LOCAL_SKIN_KERNELS(3)
DEFINE_LOCAL_SKIN_KERNELS(4)
DEFINE_LOCAL_SKIN_KERNELS(5)
DEFINE_LOCAL_SKIN_KERNELS(6)
DEFINE_LOCAL_SKIN_KERNELS(7)
DEFINE_LOCAL_SKIN_KERNELS(8)
