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
 * Built after skinning_common.cl in one program, once per joint and weight width
 * (-DQSKIN_JOINT, -DQSKIN_WEIGHT, -DQSKIN_WEIGHT_STEPS): it takes the float kernels'
 * work-item order (SKIN_VERTEX, SKIN_KEEP: four vertices per item, coalesced on a GPU),
 * Blended matrix, vertex loops and, with SKIN_LOCAL_PALETTE, staged palette and tiles; only
 * the loads and the decoding are its own. Kernels: qskin_b1..8, qskin_normals_b1..8,
 * qskin_tangents_b1..8 (normals and tangents) and their *_local_* twins. */
#if !defined(QSKIN_JOINT) || !defined(QSKIN_WEIGHT) || !defined(QSKIN_WEIGHT_STEPS)
#error "the host passes QSKIN_JOINT, QSKIN_WEIGHT and QSKIN_WEIGHT_STEPS"
#endif

/* A vertex's joints and quantized weights, as whole vectors where the layout allows. */
DEFINE_LOAD_PER_VERTEX(LoadQuantizedJoints, QSKIN_JOINT, uint)
DEFINE_LOAD_PER_VERTEX(LoadQuantizedWeights, QSKIN_WEIGHT, uint)

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
#if SKIN_LOCAL_PALETTE
DEFINE_QUANTIZED_BLEND(QuantizedBlendLocalPalette, __local)
#endif

static inline void StoreQuantizedPosition(const Blended m,
                                          const __global ushort* restrict positions,
                                          __global float* restrict out_positions,
                                          const uint v) {
  StoreTransformedPoint(m, (float)positions[3 * v], (float)positions[3 * v + 1],
                        (float)positions[3 * v + 2], out_positions, v);
}

/* The upper 3x3 of m times the decoded normal, not yet renormalised. */
static inline float3 TransformQuantizedNormal(const Blended m,
                                              const __global short* restrict normals,
                                              const float4 normal_scale, const uint v) {
  return TransformDirection(m, (float)normals[3 * v] * normal_scale.x,
                            (float)normals[3 * v + 1] * normal_scale.y,
                            (float)normals[3 * v + 2] * normal_scale.z);
}

/* The upper 3x3 of m times the decoded tangent's xyz, not yet renormalised. */
static inline float3 TransformQuantizedTangent(const Blended m,
                                               const __global short* restrict tangents,
                                               const float4 normal_scale, const uint v) {
  const float4 t = convert_float4(vload4(v, tangents)) * normal_scale;
  return TransformDirection(m, t.x, t.y, t.z);
}
#define QSKIN_NORMAL(m, v) TransformQuantizedNormal(m, normals, normal_scale, v)
#define QSKIN_TRANSFORM_TANGENT(m, v) TransformQuantizedTangent(m, tangents, normal_scale, v)

/* The skinned tangent: xyz already renormalised, w the stored handedness (+-32767) as +-1. */
static inline void StoreQuantizedTangent(const float3 xyz, const __global short* restrict tangents,
                                         __global float* restrict out_tangents, const uint v) {
  vstore4((float4)(xyz, tangents[4 * v + 3] < 0 ? -1.0f : 1.0f), v, out_tangents);
}
#define QSKIN_TANGENT(k, v) \
  StoreQuantizedTangent(s##k * tangent_inverse_length.s##k, tangents, out_tangents, v);

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

#define DEFINE_QUANTIZED_KERNELS(B)                                                          \
  DEFINE_SKIN_KERNEL_SET(qskin, B, QSKIN_ARGS, QSKIN_NORMAL_ARGS, QSKIN_TANGENT_ARGS,        \
                         QuantizedBlendPalette, StoreQuantizedPosition, QSKIN_NORMAL,        \
                         QSKIN_TRANSFORM_TANGENT, QSKIN_TANGENT)   \
  DEFINE_LOCAL_SKIN_KERNEL_SET(qskin, B, QSKIN_ARGS, QSKIN_NORMAL_ARGS, QSKIN_TANGENT_ARGS,  \
                               QuantizedBlendLocalPalette, StoreQuantizedPosition,           \
                               QSKIN_NORMAL, QSKIN_TRANSFORM_TANGENT, \
                               QSKIN_TANGENT)

DEFINE_QUANTIZED_KERNELS(1)
DEFINE_QUANTIZED_KERNELS(2)
DEFINE_QUANTIZED_KERNELS(3)
DEFINE_QUANTIZED_KERNELS(4)
DEFINE_QUANTIZED_KERNELS(5)
DEFINE_QUANTIZED_KERNELS(6)
DEFINE_QUANTIZED_KERNELS(7)
DEFINE_QUANTIZED_KERNELS(8)
