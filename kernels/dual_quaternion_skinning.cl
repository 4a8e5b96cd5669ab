/* Dual-quaternion skinning (docs/backends/dual-quaternion.md), with the semantics of the
 * CPU loops (core/engine/src/backends/scalar/scalar_dual_quaternion_skinning.h): per vertex the B
 * unit dual quaternions are blended, each one's sign chosen against the first influence
 * (q and -q are the same rotation), normalised by the real part's length and applied to
 * the position; the normal and the tangent's xyz are rotated by the blended rotation and
 * renormalised (as linear blending's: the rotation keeps a morphed normal's length, not
 * 1), the tangent's w copied.
 * The palette is the frame's DualQuaternionPalette, converted on the host once per frame:
 * 8 floats per joint, the rotation (x, y, z, w) then the dual part (x, y, z, w).
 *
 * Built in one program after skinning_common.cl and linear_blend_skinning.cl, whose
 * work-item shape it shares (SKIN_VERTEX, SKIN_KEEP, SKIN_TILES_*, SKIN_ARGS: 4 vertices
 * per item, the last item clamping to the last vertex), so the host enqueues dqs_b*, dqs_normals_b* and dqs_tangents_b* exactly as
 * skin_b*, skin_normals_b* and skin_tangents_b*. Full precision maths only (sqrt and a true division, never native_ or
 * half_), to match a float64 reference to 1e-5.
 */

/* The normalised blend of vertex v's B dual quaternions: rotation r, dual part e, from a
 * palette in either address space (__local: the *_local_* kernels, see
 * skinning_common.cl's StagePalette). */
/* Joint j's 8 floats as two aligned float4 loads (as SKIN_JOINT_ROWS01). */
#define DQS_JOINT(SPACE, quaternions, j)                   \
  (float8)(((const SPACE float4*)(quaternions))[2 * (uint)(j)], \
           ((const SPACE float4*)(quaternions))[2 * (uint)(j) + 1])
#define DEFINE_BLEND_DUAL_QUATERNIONS(NAME, SPACE)                                              \
  static inline void NAME(const SPACE void* restrict quaternions,                               \
                          const __global ushort* restrict joints,                               \
                          const __global float* restrict weights, const uint v,                 \
                          const int influences, float4* r, float4* e) {                         \
    const float8 first = DQS_JOINT(SPACE, quaternions, joints[v * influences]);                 \
    float8 b = weights[v * influences] * first;                                                 \
    _Pragma("unroll") for (int i = 1; i < influences; ++i) {                                    \
      const float8 q = DQS_JOINT(SPACE, quaternions, joints[v * influences + i]);               \
      const float dot =                                                                         \
          fma(first.s0, q.s0, fma(first.s1, q.s1, fma(first.s2, q.s2, first.s3 * q.s3)));       \
      const float w = dot < 0.0f ? -weights[v * influences + i] : weights[v * influences + i];  \
      b = fma((float8)(w), q, b);                                                               \
    }                                                                                           \
    const float inverse =                                                                       \
        1.0f / sqrt(fma(b.s0, b.s0, fma(b.s1, b.s1, fma(b.s2, b.s2, b.s3 * b.s3))));            \
    *r = b.lo * inverse;                                                                        \
    *e = b.hi * inverse;                                                                        \
  }
DEFINE_BLEND_DUAL_QUATERNIONS(BlendDualQuaternions, __global)

/* p + 2 r x (r x p + rw p): p rotated by the unit quaternion r. */
static inline float3 RotateByQuaternion(const float4 r, const float3 p) {
  const float3 c = cross(r.xyz, p) + r.w * p;
  return p + 2.0f * cross(r.xyz, c);
}

static inline void StoreDualQuaternionPosition(const float4 r, const float4 e,
                                               const __global float* restrict positions,
                                               __global float* restrict out_positions,
                                               const uint v) {
  /* Translation t = 2 (rw e - ew r + r x e), vector parts. */
  const float3 t = 2.0f * (r.w * e.xyz - e.w * r.xyz + cross(r.xyz, e.xyz));
  vstore3(RotateByQuaternion(r, vload3(v, positions)) + t, v, out_positions);
}

/* The bodies of dqs_b*, dqs_normals_b* and dqs_tangents_b*: NORMALS(r, v) stores vertex
 * v's rotated normal (DQS_NORMAL), its rotated normal and tangent (DQS_NORMAL_TANGENT: xyz
 * rotated, w the rest tangent's) or nothing (DQS_NO_NORMAL); BLEND reads PALETTE, VERTEX(k)
 * is the k-th vertex of this work-item. */
#define DQS_NORMAL(r, v) \
  vstore3(normalize(RotateByQuaternion(r, vload3(v, normals))), v, out_normals)
#define DQS_NORMAL_TANGENT(r, v)                                                           \
  DQS_NORMAL(r, v);                                                                        \
  {                                                                                        \
    const float4 tangent = vload4(v, tangents);                                            \
    vstore4((float4)(normalize(RotateByQuaternion(r, tangent.xyz)), tangent.w), v,         \
            out_tangents);                                                                 \
  }
#define DQS_NO_NORMAL(r, v)
#define DQS_BODY(B, NORMALS, BLEND, PALETTE, VERTEX)                                       \
  if (VERTEX(0) >= vertex_count) return;                                                   \
  const uint last = vertex_count - 1;                                                      \
  _Pragma("unroll") for (uint k = 0; k < SKIN_VERTICES_PER_ITEM; ++k) {                    \
    const uint raw = VERTEX(k), v = min(raw, last);                                        \
    float4 r, e;                                                                           \
    BLEND(PALETTE, joints, weights, v, B, &r, &e);                                         \
    if (SKIN_KEEP(raw, vertex_count)) {                                                    \
      StoreDualQuaternionPosition(r, e, positions, out_positions, v);                      \
      NORMALS(r, v);                                                                       \
    }                                                                                      \
  }

#define DEFINE_DUAL_QUATERNION_KERNELS(B)                                                  \
  __kernel void dqs_b##B(SKIN_ARGS) {                                                      \
    DQS_BODY(B, DQS_NO_NORMAL, BlendDualQuaternions, palette, SKIN_VERTEX)                 \
  }                                                                                        \
  __kernel void dqs_normals_b##B(SKIN_ARGS, SKIN_NORMAL_ARGS) {                            \
    DQS_BODY(B, DQS_NORMAL, BlendDualQuaternions, palette, SKIN_VERTEX)                    \
  }                                                                                        \
  __kernel void dqs_tangents_b##B(SKIN_ARGS, SKIN_TANGENT_ARGS) {                          \
    DQS_BODY(B, DQS_NORMAL_TANGENT, BlendDualQuaternions, palette, SKIN_VERTEX)            \
  }

#if SKIN_LOCAL_PALETTE
/* The palette staged in local memory: as skin_local_b* (linear_blend_skinning.cl). */
DEFINE_BLEND_DUAL_QUATERNIONS(BlendLocalDualQuaternions, __local)

#define DEFINE_LOCAL_DUAL_QUATERNION_KERNELS(B)                                            \
  __kernel void dqs_local_b##B(SKIN_ARGS, SKIN_LOCAL_ARGS) {                               \
    SKIN_TILES_BEGIN                                                                       \
      DQS_BODY(B, DQS_NO_NORMAL, BlendLocalDualQuaternions, staged, SKIN_TILE_VERTEX)      \
    SKIN_TILES_END                                                                         \
  }                                                                                        \
  __kernel void dqs_normals_local_b##B(SKIN_ARGS, SKIN_NORMAL_ARGS, SKIN_LOCAL_ARGS) {     \
    SKIN_TILES_BEGIN                                                                       \
      DQS_BODY(B, DQS_NORMAL, BlendLocalDualQuaternions, staged, SKIN_TILE_VERTEX)         \
    SKIN_TILES_END                                                                         \
  }                                                                                        \
  __kernel void dqs_tangents_local_b##B(SKIN_ARGS, SKIN_TANGENT_ARGS, SKIN_LOCAL_ARGS) {   \
    SKIN_TILES_BEGIN                                                                       \
      DQS_BODY(B, DQS_NORMAL_TANGENT, BlendLocalDualQuaternions, staged, SKIN_TILE_VERTEX) \
    SKIN_TILES_END                                                                         \
  }
#else
#define DEFINE_LOCAL_DUAL_QUATERNION_KERNELS(B)
#endif

DEFINE_DUAL_QUATERNION_KERNELS(1)
DEFINE_DUAL_QUATERNION_KERNELS(2)
DEFINE_DUAL_QUATERNION_KERNELS(3)
DEFINE_DUAL_QUATERNION_KERNELS(4)
DEFINE_DUAL_QUATERNION_KERNELS(5)
DEFINE_DUAL_QUATERNION_KERNELS(6)
DEFINE_DUAL_QUATERNION_KERNELS(7)
DEFINE_DUAL_QUATERNION_KERNELS(8)
DEFINE_LOCAL_DUAL_QUATERNION_KERNELS(1)
DEFINE_LOCAL_DUAL_QUATERNION_KERNELS(2)
DEFINE_LOCAL_DUAL_QUATERNION_KERNELS(3)
DEFINE_LOCAL_DUAL_QUATERNION_KERNELS(4)
DEFINE_LOCAL_DUAL_QUATERNION_KERNELS(5)
DEFINE_LOCAL_DUAL_QUATERNION_KERNELS(6)
DEFINE_LOCAL_DUAL_QUATERNION_KERNELS(7)
DEFINE_LOCAL_DUAL_QUATERNION_KERNELS(8)
