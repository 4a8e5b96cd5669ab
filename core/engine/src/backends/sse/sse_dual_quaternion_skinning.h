// The SSE dual-quaternion skinning kernel shared by `sse` and `sse-openmp`. Four vertices
// per step, one vertex per lane: each influence's four dual quaternions are loaded (two
// aligned registers each) and transposed, so blending, the sign against the first
// influence, normalising and the transform are plain lane-wise arithmetic with no
// horizontal sums. Positions and normals are read and written as three whole registers
// per block and (de)interleaved with shuffles. SSE2 only, like the linear kernel.
#pragma once

#include <emmintrin.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>

#include "backends/common/dual_quaternion_palette.h"
#include "backends/common/force_inline.h"
#include "backends/common/influence_dispatch.h"
#include "backends/sse/sse_blocks.h"
#include "skinserve/engine/backend.h"

namespace skinserve::sse {

// Four vertices' values of one quantity, one vertex per lane.
struct Lanes3 {
  __m128 x, y, z;
};
struct Lanes8 {
  __m128 rx, ry, rz, rw, dx, dy, dz, dw;
};

// x0 y0 z0 x1 | y1 z1 x2 y2 | z2 x3 y3 z3 -> (x0..x3), (y0..y3), (z0..z3).
SKINSERVE_FORCE_INLINE Lanes3 Deinterleave(__m128 a, __m128 b, __m128 c) {
  const __m128 b2_c1 = _mm_shuffle_ps(b, c, _MM_SHUFFLE(1, 1, 2, 2));  // b2 b2 c1 c1
  const __m128 a1_b0 = _mm_shuffle_ps(a, b, _MM_SHUFFLE(0, 0, 1, 1));  // a1 a1 b0 b0
  const __m128 b3_c2 = _mm_shuffle_ps(b, c, _MM_SHUFFLE(2, 2, 3, 3));  // b3 b3 c2 c2
  const __m128 a2_b1 = _mm_shuffle_ps(a, b, _MM_SHUFFLE(1, 1, 2, 2));  // a2 a2 b1 b1
  return {_mm_shuffle_ps(a, b2_c1, _MM_SHUFFLE(2, 0, 3, 0)),
          _mm_shuffle_ps(a1_b0, b3_c2, _MM_SHUFFLE(2, 0, 2, 0)),
          _mm_shuffle_ps(a2_b1, c, _MM_SHUFFLE(3, 0, 2, 0))};
}

// The inverse of Deinterleave: stores 12 floats at `out`.
SKINSERVE_FORCE_INLINE void StoreInterleaved(const Lanes3& v, float* out) {
  const __m128 x0_y0 = _mm_shuffle_ps(v.x, v.y, _MM_SHUFFLE(0, 0, 0, 0));  // x0 x0 y0 y0
  const __m128 z0_x1 = _mm_shuffle_ps(v.z, v.x, _MM_SHUFFLE(1, 1, 0, 0));  // z0 z0 x1 x1
  const __m128 y1_z1 = _mm_shuffle_ps(v.y, v.z, _MM_SHUFFLE(1, 1, 1, 1));  // y1 y1 z1 z1
  const __m128 x2_y2 = _mm_shuffle_ps(v.x, v.y, _MM_SHUFFLE(2, 2, 2, 2));  // x2 x2 y2 y2
  const __m128 z2_x3 = _mm_shuffle_ps(v.z, v.x, _MM_SHUFFLE(3, 3, 2, 2));  // z2 z2 x3 x3
  const __m128 y3_z3 = _mm_shuffle_ps(v.y, v.z, _MM_SHUFFLE(3, 3, 3, 3));  // y3 y3 z3 z3
  _mm_storeu_ps(out, _mm_shuffle_ps(x0_y0, z0_x1, _MM_SHUFFLE(2, 0, 2, 0)));
  _mm_storeu_ps(out + 4, _mm_shuffle_ps(y1_z1, x2_y2, _MM_SHUFFLE(2, 0, 2, 0)));
  _mm_storeu_ps(out + 8, _mm_shuffle_ps(z2_x3, y3_z3, _MM_SHUFFLE(2, 0, 2, 0)));
}

// Influence i of the four vertices: their joints' dual quaternions, transposed.
template <int B>
SKINSERVE_FORCE_INLINE Lanes8 LoadInfluence(const float* quaternions, const uint16_t* joints,
                                            int i) {
  constexpr std::size_t kStride = DualQuaternionPalette::kFloatsPerJoint;
  const float* q0 = quaternions + kStride * joints[i];
  const float* q1 = quaternions + kStride * joints[B + i];
  const float* q2 = quaternions + kStride * joints[2 * B + i];
  const float* q3 = quaternions + kStride * joints[3 * B + i];
  __m128 r0 = _mm_load_ps(q0), r1 = _mm_load_ps(q1), r2 = _mm_load_ps(q2), r3 = _mm_load_ps(q3);
  __m128 d0 = _mm_load_ps(q0 + 4), d1 = _mm_load_ps(q1 + 4), d2 = _mm_load_ps(q2 + 4),
         d3 = _mm_load_ps(q3 + 4);
  _MM_TRANSPOSE4_PS(r0, r1, r2, r3);
  _MM_TRANSPOSE4_PS(d0, d1, d2, d3);
  return {r0, r1, r2, r3, d0, d1, d2, d3};
}

// p + 2 r x (r x p + rw p), lane-wise.
SKINSERVE_FORCE_INLINE Lanes3 Rotate(const Lanes8& q, const Lanes3& p) {
  const __m128 cx =
      _mm_add_ps(_mm_sub_ps(_mm_mul_ps(q.ry, p.z), _mm_mul_ps(q.rz, p.y)), _mm_mul_ps(q.rw, p.x));
  const __m128 cy =
      _mm_add_ps(_mm_sub_ps(_mm_mul_ps(q.rz, p.x), _mm_mul_ps(q.rx, p.z)), _mm_mul_ps(q.rw, p.y));
  const __m128 cz =
      _mm_add_ps(_mm_sub_ps(_mm_mul_ps(q.rx, p.y), _mm_mul_ps(q.ry, p.x)), _mm_mul_ps(q.rw, p.z));
  const __m128 two = _mm_set1_ps(2.0f);
  return {_mm_add_ps(p.x, _mm_mul_ps(two, _mm_sub_ps(_mm_mul_ps(q.ry, cz), _mm_mul_ps(q.rz, cy)))),
          _mm_add_ps(p.y, _mm_mul_ps(two, _mm_sub_ps(_mm_mul_ps(q.rz, cx), _mm_mul_ps(q.rx, cz)))),
          _mm_add_ps(p.z, _mm_mul_ps(two, _mm_sub_ps(_mm_mul_ps(q.rx, cy), _mm_mul_ps(q.ry, cx))))};
}

// v / |v| lane-wise (a true square root and division, as the blend's): normals and tangents
// come out unit as linear blending's; the rotation keeps a morphed normal's length.
SKINSERVE_FORCE_INLINE Lanes3 Normalize(const Lanes3& v) {
  const __m128 inverse =
      _mm_div_ps(_mm_set1_ps(1.0f),
                 _mm_sqrt_ps(_mm_add_ps(_mm_add_ps(_mm_mul_ps(v.x, v.x), _mm_mul_ps(v.y, v.y)),
                                        _mm_mul_ps(v.z, v.z))));
  return {_mm_mul_ps(v.x, inverse), _mm_mul_ps(v.y, inverse), _mm_mul_ps(v.z, inverse)};
}

// Skins one block of four vertices: 12 floats of positions (and normals; 16 of tangents,
// transposed to lanes and back, w untouched) in and out.
template <int B, bool Normals, bool Tangents>
SKINSERVE_FORCE_INLINE void SkinFourDualQuaternion(const float* quaternions, const float* positions,
                                                   const float* normals, const float* tangents,
                                                   const uint16_t* joints, const float* weights,
                                                   float* out_positions, float* out_normals,
                                                   float* out_tangents) {
  // Blend: b = sum_i +-w_i q_i, the sign of each against the first influence.
  const Lanes8 first = LoadInfluence<B>(quaternions, joints, 0);
  Lanes8 b;
  {
    const __m128 w = _mm_setr_ps(weights[0], weights[B], weights[2 * B], weights[3 * B]);
    b = {_mm_mul_ps(w, first.rx), _mm_mul_ps(w, first.ry), _mm_mul_ps(w, first.rz),
         _mm_mul_ps(w, first.rw), _mm_mul_ps(w, first.dx), _mm_mul_ps(w, first.dy),
         _mm_mul_ps(w, first.dz), _mm_mul_ps(w, first.dw)};
  }
  const __m128 sign_bit = _mm_set1_ps(-0.0f);
  for (int i = 1; i < B; ++i) {
    const Lanes8 q = LoadInfluence<B>(quaternions, joints, i);
    const __m128 dot =
        _mm_add_ps(_mm_add_ps(_mm_mul_ps(first.rx, q.rx), _mm_mul_ps(first.ry, q.ry)),
                   _mm_add_ps(_mm_mul_ps(first.rz, q.rz), _mm_mul_ps(first.rw, q.rw)));
    const __m128 negative = _mm_and_ps(_mm_cmplt_ps(dot, _mm_setzero_ps()), sign_bit);
    const __m128 w = _mm_xor_ps(
        _mm_setr_ps(weights[i], weights[B + i], weights[2 * B + i], weights[3 * B + i]), negative);
    b.rx = _mm_add_ps(b.rx, _mm_mul_ps(w, q.rx));
    b.ry = _mm_add_ps(b.ry, _mm_mul_ps(w, q.ry));
    b.rz = _mm_add_ps(b.rz, _mm_mul_ps(w, q.rz));
    b.rw = _mm_add_ps(b.rw, _mm_mul_ps(w, q.rw));
    b.dx = _mm_add_ps(b.dx, _mm_mul_ps(w, q.dx));
    b.dy = _mm_add_ps(b.dy, _mm_mul_ps(w, q.dy));
    b.dz = _mm_add_ps(b.dz, _mm_mul_ps(w, q.dz));
    b.dw = _mm_add_ps(b.dw, _mm_mul_ps(w, q.dw));
  }
  // Normalise by the real part's length: a true square root and division (rsqrt's 12
  // bits would miss the 1e-5 tolerance).
  const __m128 length =
      _mm_sqrt_ps(_mm_add_ps(_mm_add_ps(_mm_mul_ps(b.rx, b.rx), _mm_mul_ps(b.ry, b.ry)),
                             _mm_add_ps(_mm_mul_ps(b.rz, b.rz), _mm_mul_ps(b.rw, b.rw))));
  const __m128 inverse = _mm_div_ps(_mm_set1_ps(1.0f), length);
  const Lanes8 q{_mm_mul_ps(b.rx, inverse), _mm_mul_ps(b.ry, inverse), _mm_mul_ps(b.rz, inverse),
                 _mm_mul_ps(b.rw, inverse), _mm_mul_ps(b.dx, inverse), _mm_mul_ps(b.dy, inverse),
                 _mm_mul_ps(b.dz, inverse), _mm_mul_ps(b.dw, inverse)};
  // Translation t = 2 (rw d - dw r + r x d), vector parts.
  const __m128 two = _mm_set1_ps(2.0f);
  const __m128 tx =
      _mm_mul_ps(two, _mm_add_ps(_mm_sub_ps(_mm_mul_ps(q.rw, q.dx), _mm_mul_ps(q.dw, q.rx)),
                                 _mm_sub_ps(_mm_mul_ps(q.ry, q.dz), _mm_mul_ps(q.rz, q.dy))));
  const __m128 ty =
      _mm_mul_ps(two, _mm_add_ps(_mm_sub_ps(_mm_mul_ps(q.rw, q.dy), _mm_mul_ps(q.dw, q.ry)),
                                 _mm_sub_ps(_mm_mul_ps(q.rz, q.dx), _mm_mul_ps(q.rx, q.dz))));
  const __m128 tz =
      _mm_mul_ps(two, _mm_add_ps(_mm_sub_ps(_mm_mul_ps(q.rw, q.dz), _mm_mul_ps(q.dw, q.rz)),
                                 _mm_sub_ps(_mm_mul_ps(q.rx, q.dy), _mm_mul_ps(q.ry, q.dx))));
  const Lanes3 p = Rotate(q, Deinterleave(_mm_loadu_ps(positions), _mm_loadu_ps(positions + 4),
                                          _mm_loadu_ps(positions + 8)));
  StoreInterleaved({_mm_add_ps(p.x, tx), _mm_add_ps(p.y, ty), _mm_add_ps(p.z, tz)}, out_positions);
  if constexpr (Normals) {
    StoreInterleaved(
        Normalize(Rotate(q, Deinterleave(_mm_loadu_ps(normals), _mm_loadu_ps(normals + 4),
                                         _mm_loadu_ps(normals + 8)))),
        out_normals);
  }
  if constexpr (Tangents) {
    __m128 x = _mm_loadu_ps(tangents), y = _mm_loadu_ps(tangents + 4);
    __m128 z = _mm_loadu_ps(tangents + 8), w = _mm_loadu_ps(tangents + 12);
    _MM_TRANSPOSE4_PS(x, y, z, w);
    const Lanes3 turned = Normalize(Rotate(q, {x, y, z}));
    x = turned.x, y = turned.y, z = turned.z;
    _MM_TRANSPOSE4_PS(x, y, z, w);
    _mm_storeu_ps(out_tangents, x), _mm_storeu_ps(out_tangents + 4, y);
    _mm_storeu_ps(out_tangents + 8, z), _mm_storeu_ps(out_tangents + 12, w);
  }
}

template <int B, bool Normals, bool Tangents>
void SkinSseDualQuaternionRange(const Mesh& mesh, const DualQuaternionPalette& palette,
                                const SkinFrame& frame, std::size_t first, std::size_t last) {
  const float* quaternions = palette.joint(0);
  ForEachBlockOfFour<B, Normals, Tangents>(
      mesh, frame, first, last,
      [&](const float* p, const float* n, const float* t, const uint16_t* j, const float* w,
          float* rp, float* rn, float* rt) __attribute__((always_inline)) {
        SkinFourDualQuaternion<B, Normals, Tangents>(quaternions, p, n, t, j, w, rp, rn, rt);
      });
}

// The dual-quaternion kernel of CpuBackend (cpu_backend.h).
struct SseDualQuaternionKernel {
  using FramePalette = DualQuaternionPalette;
  static void SkinRange(const Mesh& mesh, const FramePalette& palette, const SkinFrame& frame,
                        std::size_t first, std::size_t last) {
    WithInfluences(mesh.influences(), [&](auto b) {
      constexpr int kB = decltype(b)::value;
      if (frame.normals.empty()) {
        SkinSseDualQuaternionRange<kB, false, false>(mesh, palette, frame, first, last);
      } else if (frame.tangents.empty()) {
        SkinSseDualQuaternionRange<kB, true, false>(mesh, palette, frame, first, last);
      } else {
        SkinSseDualQuaternionRange<kB, true, true>(mesh, palette, frame, first, last);
      }
    });
  }
};

}  // namespace skinserve::sse
