/* Linear blend skinning, the paper's equations 3 and 4, one work-item per vertex.
 * skin_b1 .. skin_b8 are the same kernel specialised for B influences per vertex, so
 * the blend loop has a constant trip count the compiler unrolls (templates by macro:
 * OpenCL C 1.2 has no templates).
 * Layout: palette 12 floats per joint (3x4 row-major); positions and normals xyz per
 * vertex; joints (ushort) and weights vertex-major, joints[v * B + i]. */

#define DEFINE_SKIN_KERNEL(B)                                                              \
  __kernel void skin_b##B(__global const float* restrict palette,                          \
                          __global const float* restrict positions,                        \
                          __global const float* restrict normals,                          \
                          __global const ushort* restrict joints,                          \
                          __global const float* restrict weights,                          \
                          __global float* restrict out_positions,                          \
                          __global float* restrict out_normals, const uint vertex_count,   \
                          const uint with_normals) {                                       \
    const uint v = get_global_id(0);                                                       \
    if (v >= vertex_count) return;                                                         \
    float4 r0 = (float4)(0.0f), r1 = (float4)(0.0f), r2 = (float4)(0.0f);                  \
    for (int i = 0; i < B; ++i) {                                                          \
      const float w = weights[v * B + i];                                                  \
      const __global float* m = palette + 12 * (uint)joints[v * B + i];                    \
      r0 += w * vload4(0, m);                                                              \
      r1 += w * vload4(1, m);                                                              \
      r2 += w * vload4(2, m);                                                              \
    }                                                                                      \
    const float4 p = (float4)(vload3(v, positions), 1.0f);                                 \
    vstore3((float3)(dot(r0, p), dot(r1, p), dot(r2, p)), v, out_positions);               \
    if (with_normals) {                                                                    \
      const float4 n = (float4)(vload3(v, normals), 0.0f);                                 \
      const float3 t = (float3)(dot(r0, n), dot(r1, n), dot(r2, n));                       \
      vstore3(t / sqrt(dot(t, t)), v, out_normals);                                        \
    }                                                                                      \
  }

DEFINE_SKIN_KERNEL(1)
DEFINE_SKIN_KERNEL(2)
DEFINE_SKIN_KERNEL(3)
DEFINE_SKIN_KERNEL(4)
DEFINE_SKIN_KERNEL(5)
DEFINE_SKIN_KERNEL(6)
DEFINE_SKIN_KERNEL(7)
DEFINE_SKIN_KERNEL(8)
