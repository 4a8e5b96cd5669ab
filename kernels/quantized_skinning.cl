/* Linear blend skinning of a quantized rest stream (docs/backends/quantized-rest.md): the
 * device holds only the integers, and each vertex reads 6 bytes of position, B (or 2B) of
 * joints, B - 1 (or 2(B - 1)) of weights and 6 of normals, against 12 + 2B + 4B + 12 as
 * floats.
 *  - positions: uint16 x 3, skinned as they are: the host folded the mesh's box into the
 *    frame's palette (quantized_palette.h), so p' = M' * (q, 1).
 *  - weights: the first B - 1 as QSKIN_WEIGHT (uchar unorm8 or ushort unorm16), the last
 *    1 - their sum, blended as M_last + sum_i w_i (M_i - M_last), as the `simd` loop does.
 *  - joints: QSKIN_JOINT (uchar when J <= 256, else ushort), B per vertex.
 *  - normals: snorm16 x 3, times normal_scale (1 / the box's scale per axis: the folded
 *    palette's 3x3 carries the scale), transformed and renormalised, which absorbs 1/32767.
 *  - tangents: snorm16 x 4, xyz as the normals, w (+-32767) written as the handedness +-1.
 * Appended to linear_blend_skinning.cl in one program, built once per joint and weight
 * width (-DQSKIN_JOINT, -DQSKIN_WEIGHT, -DQSKIN_WEIGHT_STEPS): it takes that file's
 * work-item order (SKIN_VERTEX, SKIN_KEEP: four vertices per item, coalesced on a GPU), its
 * Blended matrix and, with SKIN_LOCAL_PALETTE, its staged palette and tiles. Kernels:
 * qskin_b1..8, qskin_normals_b1..8, qskin_tangents_b1..8 (normals and tangents) and their
 * *_local_* twins. */
#if !defined(QSKIN_JOINT) || !defined(QSKIN_WEIGHT) || !defined(QSKIN_WEIGHT_STEPS)
#error "the host passes QSKIN_JOINT, QSKIN_WEIGHT and QSKIN_WEIGHT_STEPS"
#endif

/* QSKIN_VECTOR(uchar, 4) is uchar4: the two levels let QSKIN_JOINT expand first. */
#define QSKIN_PASTE(type, n) type##n
#define QSKIN_VECTOR(type, n) QSKIN_PASTE(type, n)

/* `count` values of TYPE per vertex from `values[v * count ..]` into `out` (uints), as whole
 * vectors where count is a multiple of 4 or 2 (each vertex's values then start on a vector
 * boundary), as LoadInfluences does for float meshes; count is a constant. */
#define DEFINE_LOAD_PER_VERTEX(NAME, TYPE)                                                 \
  static inline void NAME(const __global TYPE* restrict values, const uint v,             \
                          const int count, uint* out) {                                    \
    if (count > 0 && count % 4 == 0) {                                                     \
      for (int g = 0; g < count / 4; ++g) {                              \
        const QSKIN_VECTOR(TYPE, 4) x =                                                    \
            ((const __global QSKIN_VECTOR(TYPE, 4)*)values)[v * (uint)(count / 4) + (uint)g]; \
        out[4 * g] = x.s0, out[4 * g + 1] = x.s1, out[4 * g + 2] = x.s2, out[4 * g + 3] = x.s3; \
      }                                                                                    \
    } else if (count > 0 && count % 2 == 0) {                                              \
      for (int g = 0; g < count / 2; ++g) {                              \
        const QSKIN_VECTOR(TYPE, 2) x =                                                    \
            ((const __global QSKIN_VECTOR(TYPE, 2)*)values)[v * (uint)(count / 2) + (uint)g]; \
        out[2 * g] = x.s0, out[2 * g + 1] = x.s1;                                          \
      }                                                                                    \
    } else {                                                                               \
      for (int i = 0; i < count; ++i) out[i] = values[v * count + i];   \
    }                                                                                      \
  }
DEFINE_LOAD_PER_VERTEX(LoadQuantizedJoints, QSKIN_JOINT)
DEFINE_LOAD_PER_VERTEX(LoadQuantizedWeights, QSKIN_WEIGHT)

/* The blend from a palette in either address space. B = 1: the one joint's matrix. */
#define DEFINE_QUANTIZED_BLEND(NAME, SPACE)                                                \
  static inline Blended NAME(const SPACE void* restrict palette,                           \
                             const __global QSKIN_JOINT* restrict joints,                  \
                             const __global QSKIN_WEIGHT* restrict weights, const uint v,  \
                             const int influences) {                                       \
    uint joint[8], weight[8];                                                              \
    LoadQuantizedJoints(joints, v, influences, joint);                                     \
    LoadQuantizedWeights(weights, v, influences - 1, weight);                              \
    const uint last = joint[influences - 1];                                               \
    const Blended base = {SKIN_JOINT_ROWS01(SPACE, palette, last),                         \
                          SKIN_JOINT_ROW2(SPACE, palette, last)};                          \
    Blended m = base;                                                                      \
    _Pragma("unroll") for (int i = 0; i < influences - 1; ++i) {                           \
      const float w = (float)weight[i] * (1.0f / (float)QSKIN_WEIGHT_STEPS);               \
      m.r01 = fma((float8)(w), SKIN_JOINT_ROWS01(SPACE, palette, joint[i]) - base.r01, m.r01); \
      m.r2 = fma((float4)(w), SKIN_JOINT_ROW2(SPACE, palette, joint[i]) - base.r2, m.r2);  \
    }                                                                                      \
    return m;                                                                              \
  }
DEFINE_QUANTIZED_BLEND(QuantizedBlendPalette, __global)

static inline void StoreQuantizedPosition(const Blended m,
                                          const __global ushort* restrict positions,
                                          __global float* restrict out_positions,
                                          const uint v) {
  const float x = (float)positions[3 * v], y = (float)positions[3 * v + 1],
              z = (float)positions[3 * v + 2];
  out_positions[3 * v] = fma(m.r01.s0, x, fma(m.r01.s1, y, fma(m.r01.s2, z, m.r01.s3)));
  out_positions[3 * v + 1] = fma(m.r01.s4, x, fma(m.r01.s5, y, fma(m.r01.s6, z, m.r01.s7)));
  out_positions[3 * v + 2] = fma(m.r2.s0, x, fma(m.r2.s1, y, fma(m.r2.s2, z, m.r2.s3)));
}

/* The upper 3x3 of m times the decoded normal, not yet renormalised. */
static inline float3 TransformQuantizedNormal(const Blended m,
                                              const __global short* restrict normals,
                                              const float4 normal_scale, const uint v) {
  const float x = (float)normals[3 * v] * normal_scale.x,
              y = (float)normals[3 * v + 1] * normal_scale.y,
              z = (float)normals[3 * v + 2] * normal_scale.z;
  return (float3)(fma(m.r01.s0, x, fma(m.r01.s1, y, m.r01.s2 * z)),
                  fma(m.r01.s4, x, fma(m.r01.s5, y, m.r01.s6 * z)),
                  fma(m.r2.s0, x, fma(m.r2.s1, y, m.r2.s2 * z)));
}

/* The upper 3x3 of m times the decoded tangent's xyz, not yet renormalised. */
static inline float3 TransformQuantizedTangent(const Blended m,
                                               const __global short* restrict tangents,
                                               const float4 normal_scale, const uint v) {
  const float4 t = convert_float4(vload4(v, tangents)) * normal_scale;
  return (float3)(fma(m.r01.s0, t.x, fma(m.r01.s1, t.y, m.r01.s2 * t.z)),
                  fma(m.r01.s4, t.x, fma(m.r01.s5, t.y, m.r01.s6 * t.z)),
                  fma(m.r2.s0, t.x, fma(m.r2.s1, t.y, m.r2.s2 * t.z)));
}

/* The skinned tangent: xyz already renormalised, w the stored handedness (+-32767) as +-1. */
static inline void StoreQuantizedTangent(const float3 xyz, const __global short* restrict tangents,
                                         __global float* restrict out_tangents, const uint v) {
  vstore4((float4)(xyz, tangents[4 * v + 3] < 0 ? -1.0f : 1.0f), v, out_tangents);
}

#define QSKIN_ARGS                                                                          \
  const __global float *restrict palette, const __global QSKIN_JOINT *restrict joints,      \
      const __global QSKIN_WEIGHT *restrict weights,                                        \
      const __global ushort *restrict positions, __global float *restrict out_positions,    \
      const uint vertex_count
#define QSKIN_NORMAL_ARGS                                                                   \
  const __global short *restrict normals, __global float *restrict out_normals,             \
      const float4 normal_scale
#define QSKIN_TANGENT_ARGS \
  QSKIN_NORMAL_ARGS, const __global short *restrict tangents, __global float *restrict out_tangents

#define QSKIN_POSITIONS_BODY(B, BLEND, PALETTE, VERTEX)                                    \
  if (VERTEX(0) >= vertex_count) return;                                                   \
  const uint last = vertex_count - 1;                                                      \
  _Pragma("unroll") for (uint k = 0; k < SKIN_VERTICES_PER_ITEM; ++k) {                    \
    const uint raw = VERTEX(k), v = min(raw, last);                                        \
    const Blended m = BLEND(PALETTE, joints, weights, v, B);                               \
    if (SKIN_KEEP(raw, vertex_count)) StoreQuantizedPosition(m, positions, out_positions, v); \
  }

/* TANGENTS_PREPARE and TANGENT(k, v) as in SKIN_NORMALS_BODY: the tangents decoded,
 * transformed and sharing one vector rsqrt (QSKIN_TANGENTS_*), or nothing
 * (SKIN_NO_TANGENTS_*). */
#define QSKIN_TANGENTS_PREPARE                                                             \
  const float3 s0 = TransformQuantizedTangent(m0, tangents, normal_scale, v0),             \
               s1 = TransformQuantizedTangent(m1, tangents, normal_scale, v1),             \
               s2 = TransformQuantizedTangent(m2, tangents, normal_scale, v2),             \
               s3 = TransformQuantizedTangent(m3, tangents, normal_scale, v3);             \
  const float4 tangent_inverse_length =                                                    \
      rsqrt((float4)(SquaredLength(s0), SquaredLength(s1), SquaredLength(s2),              \
                     SquaredLength(s3)));
#define QSKIN_TANGENT(k, v) \
  StoreQuantizedTangent(s##k * tangent_inverse_length.s##k, tangents, out_tangents, v);

/* Four vertices share one vector rsqrt, as in skin_normals_b*. */
#define QSKIN_NORMALS_BODY(B, BLEND, PALETTE, VERTEX, TANGENTS_PREPARE, TANGENT)           \
  const uint r0 = VERTEX(0), r1 = VERTEX(1), r2 = VERTEX(2), r3 = VERTEX(3);               \
  if (r0 >= vertex_count) return;                                                          \
  const uint last = vertex_count - 1;                                                      \
  const uint v0 = r0, v1 = min(r1, last), v2 = min(r2, last), v3 = min(r3, last);          \
  const Blended m0 = BLEND(PALETTE, joints, weights, v0, B);                               \
  const Blended m1 = BLEND(PALETTE, joints, weights, v1, B);                               \
  const Blended m2 = BLEND(PALETTE, joints, weights, v2, B);                               \
  const Blended m3 = BLEND(PALETTE, joints, weights, v3, B);                               \
  const float3 t0 = TransformQuantizedNormal(m0, normals, normal_scale, v0),               \
               t1 = TransformQuantizedNormal(m1, normals, normal_scale, v1),               \
               t2 = TransformQuantizedNormal(m2, normals, normal_scale, v2),               \
               t3 = TransformQuantizedNormal(m3, normals, normal_scale, v3);               \
  const float4 inverse_length =                                                            \
      rsqrt((float4)(SquaredLength(t0), SquaredLength(t1), SquaredLength(t2),              \
                     SquaredLength(t3)));                                                  \
  TANGENTS_PREPARE                                                                         \
  StoreQuantizedPosition(m0, positions, out_positions, v0);                                \
  vstore3(t0 * inverse_length.s0, v0, out_normals);                                        \
  TANGENT(0, v0)                                                                           \
  if (SKIN_KEEP(r1, vertex_count)) {                                                       \
    StoreQuantizedPosition(m1, positions, out_positions, v1);                              \
    vstore3(t1 * inverse_length.s1, v1, out_normals);                                      \
    TANGENT(1, v1)                                                                         \
  }                                                                                        \
  if (SKIN_KEEP(r2, vertex_count)) {                                                       \
    StoreQuantizedPosition(m2, positions, out_positions, v2);                              \
    vstore3(t2 * inverse_length.s2, v2, out_normals);                                      \
    TANGENT(2, v2)                                                                         \
  }                                                                                        \
  if (SKIN_KEEP(r3, vertex_count)) {                                                       \
    StoreQuantizedPosition(m3, positions, out_positions, v3);                              \
    vstore3(t3 * inverse_length.s3, v3, out_normals);                                      \
    TANGENT(3, v3)                                                                         \
  }

#define DEFINE_QUANTIZED_KERNELS(B)                                                        \
  __kernel void qskin_b##B(QSKIN_ARGS) {                                                   \
    QSKIN_POSITIONS_BODY(B, QuantizedBlendPalette, palette, SKIN_VERTEX)                   \
  }                                                                                        \
  __kernel void qskin_normals_b##B(QSKIN_ARGS, QSKIN_NORMAL_ARGS) {                        \
    QSKIN_NORMALS_BODY(B, QuantizedBlendPalette, palette, SKIN_VERTEX,                     \
                       SKIN_NO_TANGENTS_PREPARE, SKIN_NO_TANGENT)                          \
  }                                                                                        \
  __kernel void qskin_tangents_b##B(QSKIN_ARGS, QSKIN_TANGENT_ARGS) {                      \
    QSKIN_NORMALS_BODY(B, QuantizedBlendPalette, palette, SKIN_VERTEX,                     \
                       QSKIN_TANGENTS_PREPARE, QSKIN_TANGENT)                              \
  }

#if SKIN_LOCAL_PALETTE
DEFINE_QUANTIZED_BLEND(QuantizedBlendLocalPalette, __local)
#define DEFINE_QUANTIZED_LOCAL_KERNELS(B)                                                  \
  __kernel void qskin_local_b##B(QSKIN_ARGS, SKIN_LOCAL_ARGS) {                            \
    StagePalette(palette, staged, palette_floats);                                         \
    for (uint tile = 0; tile < SKIN_LOCAL_TILES; ++tile) {                                 \
      const uint tile_base = SKIN_TILE_BASE(tile);                                         \
      QSKIN_POSITIONS_BODY(B, QuantizedBlendLocalPalette, staged, SKIN_TILE_VERTEX)        \
    }                                                                                      \
  }                                                                                        \
  __kernel void qskin_normals_local_b##B(QSKIN_ARGS, QSKIN_NORMAL_ARGS, SKIN_LOCAL_ARGS) { \
    StagePalette(palette, staged, palette_floats);                                         \
    for (uint tile = 0; tile < SKIN_LOCAL_TILES; ++tile) {                                 \
      const uint tile_base = SKIN_TILE_BASE(tile);                                         \
      QSKIN_NORMALS_BODY(B, QuantizedBlendLocalPalette, staged, SKIN_TILE_VERTEX,          \
                         SKIN_NO_TANGENTS_PREPARE, SKIN_NO_TANGENT)                        \
    }                                                                                      \
  }                                                                                        \
  __kernel void qskin_tangents_local_b##B(QSKIN_ARGS, QSKIN_TANGENT_ARGS, SKIN_LOCAL_ARGS) { \
    StagePalette(palette, staged, palette_floats);                                         \
    for (uint tile = 0; tile < SKIN_LOCAL_TILES; ++tile) {                                 \
      const uint tile_base = SKIN_TILE_BASE(tile);                                         \
      QSKIN_NORMALS_BODY(B, QuantizedBlendLocalPalette, staged, SKIN_TILE_VERTEX,          \
                         QSKIN_TANGENTS_PREPARE, QSKIN_TANGENT)                            \
    }                                                                                      \
  }
#else
#define DEFINE_QUANTIZED_LOCAL_KERNELS(B)
#endif

DEFINE_QUANTIZED_KERNELS(1)
DEFINE_QUANTIZED_KERNELS(2)
DEFINE_QUANTIZED_KERNELS(3)
DEFINE_QUANTIZED_KERNELS(4)
DEFINE_QUANTIZED_KERNELS(5)
DEFINE_QUANTIZED_KERNELS(6)
DEFINE_QUANTIZED_KERNELS(7)
DEFINE_QUANTIZED_KERNELS(8)
DEFINE_QUANTIZED_LOCAL_KERNELS(1)
DEFINE_QUANTIZED_LOCAL_KERNELS(2)
DEFINE_QUANTIZED_LOCAL_KERNELS(3)
DEFINE_QUANTIZED_LOCAL_KERNELS(4)
DEFINE_QUANTIZED_LOCAL_KERNELS(5)
DEFINE_QUANTIZED_LOCAL_KERNELS(6)
DEFINE_QUANTIZED_LOCAL_KERNELS(7)
DEFINE_QUANTIZED_LOCAL_KERNELS(8)
