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
 * On a GPU the same kernels run with a coalesced vertex order (SKIN_VERTEX), and with
 * SKIN_LOCAL_PALETTE the *_local_* kernels stage the palette in local memory first (the
 * vertex order, the bodies, the kernel sets and the staging are in skinning_common.cl,
 * built first and shared with quantized_skinning.cl). Palette records, joints and weights
 * are read as aligned vectors (float4 rows, DEFINE_LOAD_PER_VERTEX): vload8/vload4 on a
 * float pointer promise only a float's alignment, and NVIDIA's compiler made them scalar
 * loads, which halved the kernel's speed on an H200 (docs/backends/opencl.md#aligned-loads).
 * Normals use rsqrt (a sqrt and a true division on this device): full precision, never
 * native_ or half_ maths, so they match a float64 reference to 1e-5.
 */

/* Vertex v's B joints and weights, as whole vectors where the layout allows. */
DEFINE_LOAD_PER_VERTEX(LoadJoints, ushort, uint)
DEFINE_LOAD_PER_VERTEX(LoadWeights, float, float)

/* The blend from a palette in either address space: __global (every kernel but the
 * *_local_* ones) or __local (those, after StagePalette). */
#define DEFINE_BLEND_PALETTE(NAME, SPACE)                                                  \
  static inline Blended NAME(const SPACE void* restrict palette,                           \
                             const __global ushort* restrict joints,                       \
                             const __global float* restrict weights, const uint v,         \
                             const int influences) {                                       \
    uint joint[8];                                                                         \
    float weight[8];                                                                       \
    LoadJoints(joints, v, influences, joint);                                              \
    LoadWeights(weights, v, influences, weight);                                           \
    Blended m = {(float8)(0.0f), (float4)(0.0f)};                                          \
    _Pragma("unroll") for (int i = 0; i < influences; ++i) {                               \
      m.r01 = fma((float8)(weight[i]), SKIN_JOINT_ROWS01(SPACE, palette, joint[i]), m.r01); \
      m.r2 = fma((float4)(weight[i]), SKIN_JOINT_ROW2(SPACE, palette, joint[i]), m.r2);    \
    }                                                                                      \
    return m;                                                                              \
  }
DEFINE_BLEND_PALETTE(BlendPalette, __global)
#if SKIN_LOCAL_PALETTE
DEFINE_BLEND_PALETTE(BlendLocalPalette, __local)
#endif

static inline void StorePosition(const Blended m, const __global float* restrict positions,
                                 __global float* restrict out_positions, const uint v) {
  StoreTransformedPoint(m, positions[3 * v], positions[3 * v + 1], positions[3 * v + 2],
                        out_positions, v);
}

/* Vertex v's normal and tangent (xyz of 4 floats per vertex) times m's upper 3x3. */
#define SKIN_NORMAL(m, v) TransformDirection(m, normals[3 * (v)], normals[3 * (v) + 1], normals[3 * (v) + 2])
#define SKIN_TRANSFORM_TANGENT(m, v) \
  TransformDirection(m, tangents[4 * (v)], tangents[4 * (v) + 1], tangents[4 * (v) + 2])

/* The skinned tangent: xyz already renormalised, w the rest tangent's (never transformed). */
static inline void StoreTangent(const float3 xyz, const __global float* restrict tangents,
                                __global float* restrict out_tangents, const uint v) {
  vstore4((float4)(xyz, tangents[4 * v + 3]), v, out_tangents);
}
#define SKIN_TANGENT(k, v) \
  StoreTangent(s##k * tangent_inverse_length.s##k, tangents, out_tangents, v);

/* The float kernels' arguments, shared with dual_quaternion_skinning.cl. */
#define SKIN_ARGS                                                                          \
  const __global float *restrict palette, const __global ushort *restrict joints,          \
      const __global float *restrict weights, const __global float *restrict positions,    \
      __global float *restrict out_positions, const uint vertex_count
/* The normals' and the tangents' arguments, after SKIN_ARGS. */
#define SKIN_NORMAL_ARGS \
  const __global float *restrict normals, __global float *restrict out_normals
#define SKIN_TANGENT_ARGS \
  SKIN_NORMAL_ARGS, const __global float *restrict tangents, __global float *restrict out_tangents

/* skin_b1..8, skin_normals_b1..8, skin_tangents_b1..8 and their *_local_* twins. */
#define DEFINE_SKIN_KERNELS(B)                                                              \
  DEFINE_SKIN_KERNEL_SET(skin, B, SKIN_ARGS, SKIN_NORMAL_ARGS, SKIN_TANGENT_ARGS,           \
                         BlendPalette, StorePosition, SKIN_NORMAL,                          \
                         SKIN_TRANSFORM_TANGENT, SKIN_TANGENT)    \
  DEFINE_LOCAL_SKIN_KERNEL_SET(skin, B, SKIN_ARGS, SKIN_NORMAL_ARGS, SKIN_TANGENT_ARGS,     \
                               BlendLocalPalette, StorePosition, SKIN_NORMAL,               \
                               SKIN_TRANSFORM_TANGENT, SKIN_TANGENT)

DEFINE_SKIN_KERNELS(1)
DEFINE_SKIN_KERNELS(2)
DEFINE_SKIN_KERNELS(3)
DEFINE_SKIN_KERNELS(4)
DEFINE_SKIN_KERNELS(5)
DEFINE_SKIN_KERNELS(6)
DEFINE_SKIN_KERNELS(7)
DEFINE_SKIN_KERNELS(8)
