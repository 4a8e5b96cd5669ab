/* What every skinning kernel shares (linear_blend_skinning.cl, its quantized twin
 * quantized_skinning.cl, dual_quaternion_skinning.cl): the work-item order, the blended
 * matrix and its transforms, the vertex loop of the positions and normals kernels, the
 * palette staged in local memory, and the kernel sets each family defines from them.
 * The host builds it as the first source string of every skinning program
 * (BuildSkinningProgram in opencl_runtime.cpp says why that and not an #include).
 * linear_blend_skinning.cl says why the kernels have this shape (measured on PoCL and an
 * H200); nothing here is native_ or half_ maths. */

/* The host passes -DSKIN_VERTICES_PER_ITEM, -DSKIN_ITEMS_PER_GROUP, -DSKIN_COALESCED and
 * -DSKIN_LOCAL_PALETTE (0, or 1 with -DSKIN_LOCAL_TILES); the normals kernels are written
 * out for four vertices per item. */
#if !defined(SKIN_VERTICES_PER_ITEM) || SKIN_VERTICES_PER_ITEM != 4
#error "SKIN_VERTICES_PER_ITEM must be 4 (kVerticesPerItem in core/engine/src/backends/opencl/opencl_runtime.cpp)"
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

/* SKIN_VECTOR(uchar, 4) is uchar4: the two levels let a macro type expand first. */
#define SKIN_PASTE(type, n) type##n
#define SKIN_VECTOR(type, n) SKIN_PASTE(type, n)

/* `count` values of TYPE per vertex from `values[v * count ..]` into `out` (of OUT), as
 * whole vectors where count is a multiple of 4 or 2 (each vertex's values then start on a
 * vector boundary, and the buffers' bases are aligned far beyond that): on a GPU one
 * 16-byte load instead of four 4-byte ones (vload4 on a scalar pointer promises no more
 * than the scalar's alignment, so it compiles to scalar loads). count is a constant: one
 * branch survives. */
#define DEFINE_LOAD_PER_VERTEX(NAME, TYPE, OUT)                                               \
  static inline void NAME(const __global TYPE* restrict values, const uint v,                \
                          const int count, OUT* out) {                                        \
    if (count > 0 && count % 4 == 0) {                                                        \
      for (int g = 0; g < count / 4; ++g) {                                                   \
        const SKIN_VECTOR(TYPE, 4) x =                                                        \
            ((const __global SKIN_VECTOR(TYPE, 4)*)values)[v * (uint)(count / 4) + (uint)g]; \
        out[4 * g] = x.s0, out[4 * g + 1] = x.s1, out[4 * g + 2] = x.s2, out[4 * g + 3] = x.s3; \
      }                                                                                       \
    } else if (count > 0 && count % 2 == 0) {                                                 \
      for (int g = 0; g < count / 2; ++g) {                                                   \
        const SKIN_VECTOR(TYPE, 2) x =                                                        \
            ((const __global SKIN_VECTOR(TYPE, 2)*)values)[v * (uint)(count / 2) + (uint)g]; \
        out[2 * g] = x.s0, out[2 * g + 1] = x.s1;                                             \
      }                                                                                       \
    } else {                                                                                  \
      for (int i = 0; i < count; ++i) out[i] = values[v * count + i];                         \
    }                                                                                         \
  }

/* Rows 0-1 and row 2 of one vertex's blended 3x4 matrix. */
typedef struct {
  float8 r01;
  float4 r2;
} Blended;

/* A joint's 12 floats as three aligned float4 loads (the palette's base is aligned: a
 * buffer's, or a __local float4 array's). */
#define SKIN_JOINT_ROWS01(SPACE, palette, j) \
  (float8)(((const SPACE float4*)(palette))[3 * (j)], ((const SPACE float4*)(palette))[3 * (j) + 1])
#define SKIN_JOINT_ROW2(SPACE, palette, j) (((const SPACE float4*)(palette))[3 * (j) + 2])

/* m * (x, y, z, 1) written to out_positions[3v ..], as scalar FMAs. */
static inline void StoreTransformedPoint(const Blended m, const float x, const float y,
                                         const float z, __global float* restrict out_positions,
                                         const uint v) {
  out_positions[3 * v] = fma(m.r01.s0, x, fma(m.r01.s1, y, fma(m.r01.s2, z, m.r01.s3)));
  out_positions[3 * v + 1] = fma(m.r01.s4, x, fma(m.r01.s5, y, fma(m.r01.s6, z, m.r01.s7)));
  out_positions[3 * v + 2] = fma(m.r2.s0, x, fma(m.r2.s1, y, fma(m.r2.s2, z, m.r2.s3)));
}

/* The upper 3x3 of m times (x, y, z): a normal or a tangent, not yet renormalised. */
static inline float3 TransformDirection(const Blended m, const float x, const float y,
                                        const float z) {
  return (float3)(fma(m.r01.s0, x, fma(m.r01.s1, y, m.r01.s2 * z)),
                  fma(m.r01.s4, x, fma(m.r01.s5, y, m.r01.s6 * z)),
                  fma(m.r2.s0, x, fma(m.r2.s1, y, m.r2.s2 * z)));
}

static inline float SquaredLength(const float3 t) { return fma(t.x, t.x, fma(t.y, t.y, t.z * t.z)); }

/* The positions kernels' body: BLEND reads PALETTE, VERTEX(k) is the k-th vertex of this
 * work-item, STORE(m, positions, out_positions, v) transforms and stores vertex v. */
#define SKIN_POSITIONS_BODY(B, BLEND, PALETTE, VERTEX, STORE)                              \
  if (VERTEX(0) >= vertex_count) return;                                                   \
  const uint last = vertex_count - 1;                                                      \
  _Pragma("unroll") for (uint k = 0; k < SKIN_VERTICES_PER_ITEM; ++k) {                    \
    const uint raw = VERTEX(k), v = min(raw, last);                                        \
    const Blended m = BLEND(PALETTE, joints, weights, v, B);                               \
    if (SKIN_KEEP(raw, vertex_count)) STORE(m, positions, out_positions, v);               \
  }

/* TANGENTS_PREPARE(TRANSFORM) and TANGENT(k, v) (a statement with its own semicolon) add
 * the tangents to the normals' body: the four tangents transformed by TRANSFORM(m, v) and
 * sharing one vector rsqrt, as the normals do (SKIN_TANGENTS_PREPARE_OF and each family's
 * TANGENT), or nothing at all (SKIN_NO_TANGENTS_*: a normals kernel preprocesses to the
 * very text it had before tangents existed). Macro names, not text, travel through the
 * kernel-set macros: text with commas would split into arguments one level down. */
#define SKIN_NO_TANGENTS_PREPARE(TRANSFORM)
#define SKIN_NO_TANGENT(k, v)
#define SKIN_TANGENTS_PREPARE_OF(TRANSFORM)                                                \
  const float3 s0 = TRANSFORM(m0, v0), s1 = TRANSFORM(m1, v1), s2 = TRANSFORM(m2, v2),     \
               s3 = TRANSFORM(m3, v3);                                                     \
  const float4 tangent_inverse_length =                                                    \
      rsqrt((float4)(SquaredLength(s0), SquaredLength(s1), SquaredLength(s2),              \
                     SquaredLength(s3)));

/* The normals (and tangents) kernels' body: four vertices share one vector rsqrt.
 * NORMAL(m, v) is vertex v's normal transformed by m, not yet renormalised. */
#define SKIN_NORMALS_BODY(B, BLEND, PALETTE, VERTEX, STORE, NORMAL, TANGENTS_PREPARE,       \
                          TRANSFORM_TANGENT, TANGENT)                                         \
  const uint r0 = VERTEX(0), r1 = VERTEX(1), r2 = VERTEX(2), r3 = VERTEX(3);                  \
  if (r0 >= vertex_count) return;                                                             \
  const uint last = vertex_count - 1;                                                         \
  const uint v0 = r0, v1 = min(r1, last), v2 = min(r2, last), v3 = min(r3, last);             \
  const Blended m0 = BLEND(PALETTE, joints, weights, v0, B);                                  \
  const Blended m1 = BLEND(PALETTE, joints, weights, v1, B);                                  \
  const Blended m2 = BLEND(PALETTE, joints, weights, v2, B);                                  \
  const Blended m3 = BLEND(PALETTE, joints, weights, v3, B);                                  \
  const float3 t0 = NORMAL(m0, v0), t1 = NORMAL(m1, v1), t2 = NORMAL(m2, v2),                 \
               t3 = NORMAL(m3, v3);                                                           \
  const float4 inverse_length =                                                               \
      rsqrt((float4)(SquaredLength(t0), SquaredLength(t1), SquaredLength(t2),                 \
                     SquaredLength(t3)));                                                     \
  TANGENTS_PREPARE(TRANSFORM_TANGENT)                                                         \
  STORE(m0, positions, out_positions, v0);                                                    \
  vstore3(t0 * inverse_length.s0, v0, out_normals);                                           \
  TANGENT(0, v0)                                                                              \
  if (SKIN_KEEP(r1, vertex_count)) {                                                          \
    STORE(m1, positions, out_positions, v1);                                                  \
    vstore3(t1 * inverse_length.s1, v1, out_normals);                                         \
    TANGENT(1, v1)                                                                            \
  }                                                                                           \
  if (SKIN_KEEP(r2, vertex_count)) {                                                          \
    STORE(m2, positions, out_positions, v2);                                                  \
    vstore3(t2 * inverse_length.s2, v2, out_normals);                                         \
    TANGENT(2, v2)                                                                            \
  }                                                                                           \
  if (SKIN_KEEP(r3, vertex_count)) {                                                          \
    STORE(m3, positions, out_positions, v3);                                                  \
    vstore3(t3 * inverse_length.s3, v3, out_normals);                                         \
    TANGENT(3, v3)                                                                            \
  }

/* One family's kernels for B influences: PREFIX_bB (positions), PREFIX_normals_bB and
 * PREFIX_tangents_bB (normals and tangents: a frame with tangents always has normals), with
 * the family's arguments, blend, store and transforms. */
#define DEFINE_SKIN_KERNEL_SET(PREFIX, B, ARGS, NORMAL_ARGS, TANGENT_ARGS, BLEND, STORE,      \
                               NORMAL, TRANSFORM_TANGENT, TANGENT)                            \
  __kernel void PREFIX##_b##B(ARGS) {                                                         \
    SKIN_POSITIONS_BODY(B, BLEND, palette, SKIN_VERTEX, STORE)                                \
  }                                                                                           \
  __kernel void PREFIX##_normals_b##B(ARGS, NORMAL_ARGS) {                                    \
    SKIN_NORMALS_BODY(B, BLEND, palette, SKIN_VERTEX, STORE, NORMAL, SKIN_NO_TANGENTS_PREPARE, \
                      TRANSFORM_TANGENT, SKIN_NO_TANGENT)                                     \
  }                                                                                           \
  __kernel void PREFIX##_tangents_b##B(ARGS, TANGENT_ARGS) {                                  \
    SKIN_NORMALS_BODY(B, BLEND, palette, SKIN_VERTEX, STORE, NORMAL, SKIN_TANGENTS_PREPARE_OF, \
                      TRANSFORM_TANGENT, TANGENT)                                             \
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
/* The start of a *_local_* kernel: the palette staged, then a loop over the group's tiles
 * (closed by SKIN_TILES_END) that declares `tile_base`. Tiles ascend: an item whose first
 * vertex of a tile is past the end returns (the body's `return`), and so would it for
 * every later tile. */
#define SKIN_TILES_BEGIN                                                                   \
  StagePalette(palette, staged, palette_floats);                                           \
  for (uint tile = 0; tile < SKIN_LOCAL_TILES; ++tile) {                                   \
    const uint tile_base = SKIN_TILE_BASE(tile);
#define SKIN_TILES_END }

/* DEFINE_SKIN_KERNEL_SET's *_local_* twins (PREFIX_local_bB, ...), blending with
 * LOCAL_BLEND from the staged palette. */
#define DEFINE_LOCAL_SKIN_KERNEL_SET(PREFIX, B, ARGS, NORMAL_ARGS, TANGENT_ARGS, LOCAL_BLEND,  \
                                     STORE, NORMAL, TRANSFORM_TANGENT, TANGENT)                \
  __kernel void PREFIX##_local_b##B(ARGS, SKIN_LOCAL_ARGS) {                                   \
    SKIN_TILES_BEGIN                                                                           \
    SKIN_POSITIONS_BODY(B, LOCAL_BLEND, staged, SKIN_TILE_VERTEX, STORE)                       \
    SKIN_TILES_END                                                                             \
  }                                                                                            \
  __kernel void PREFIX##_normals_local_b##B(ARGS, NORMAL_ARGS, SKIN_LOCAL_ARGS) {              \
    SKIN_TILES_BEGIN                                                                           \
    SKIN_NORMALS_BODY(B, LOCAL_BLEND, staged, SKIN_TILE_VERTEX, STORE, NORMAL,                 \
                      SKIN_NO_TANGENTS_PREPARE, TRANSFORM_TANGENT, SKIN_NO_TANGENT)            \
    SKIN_TILES_END                                                                             \
  }                                                                                            \
  __kernel void PREFIX##_tangents_local_b##B(ARGS, TANGENT_ARGS, SKIN_LOCAL_ARGS) {            \
    SKIN_TILES_BEGIN                                                                           \
    SKIN_NORMALS_BODY(B, LOCAL_BLEND, staged, SKIN_TILE_VERTEX, STORE, NORMAL,                 \
                      SKIN_TANGENTS_PREPARE_OF, TRANSFORM_TANGENT, TANGENT)                    \
    SKIN_TILES_END                                                                             \
  }
#else
#define DEFINE_LOCAL_SKIN_KERNEL_SET(PREFIX, B, ARGS, NORMAL_ARGS, TANGENT_ARGS, LOCAL_BLEND, \
                                     STORE, NORMAL, TRANSFORM_TANGENT, TANGENT)
#endif
