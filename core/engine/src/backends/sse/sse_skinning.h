// The SSE skinning kernel shared by `sse` and `sse-openmp`. Matrices are blended a column
// per register from the frame's ColumnPalette (equation 3, 4 lanes per instruction), and
// vertices go four at a time, so positions and normals are read and written as three
// whole registers per block instead of float by float. SSE2 only (baseline x86-64): it
// runs on any 64-bit x86 the image runs on. Measured against the paper's layout (matrix
// rows per register, a transpose per vertex) it is 1.2-1.7x faster on positions and
// 1.4-1.8x with normals.
#pragma once

#include <emmintrin.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>

#include "backends/common/force_inline.h"
#include "backends/common/influence_dispatch.h"
#include "backends/sse/sse_blocks.h"
#include "backends/sse/sse_column_palette.h"
#include "skinserve/engine/backend.h"

namespace skinserve::sse {

template <int Lane>
SKINSERVE_FORCE_INLINE __m128 Broadcast(__m128 v) {
  return _mm_shuffle_ps(v, v, _MM_SHUFFLE(Lane, Lane, Lane, Lane));
}

struct Columns {
  __m128 c0, c1, c2, c3;
};

// Equation 3: the blended matrix of one vertex, column by column.
// `columns`: ColumnPalette::joint(0), held in a local so that the output stores, which
// might alias the ColumnPalette, do not force a reload per vertex.
template <int B>
SKINSERVE_FORCE_INLINE Columns Blend(const float* columns, const uint16_t* joints,
                                     const float* weights) {
  constexpr std::size_t kStride = ColumnPalette::kFloatsPerJoint;
  __m128 w = _mm_set1_ps(weights[0]);
  const float* m = columns + kStride * joints[0];
  Columns c{_mm_mul_ps(w, _mm_load_ps(m)), _mm_mul_ps(w, _mm_load_ps(m + 4)),
            _mm_mul_ps(w, _mm_load_ps(m + 8)), _mm_mul_ps(w, _mm_load_ps(m + 12))};
  for (int i = 1; i < B; ++i) {
    w = _mm_set1_ps(weights[i]);
    m = columns + kStride * joints[i];
    c.c0 = _mm_add_ps(c.c0, _mm_mul_ps(w, _mm_load_ps(m)));
    c.c1 = _mm_add_ps(c.c1, _mm_mul_ps(w, _mm_load_ps(m + 4)));
    c.c2 = _mm_add_ps(c.c2, _mm_mul_ps(w, _mm_load_ps(m + 8)));
    c.c3 = _mm_add_ps(c.c3, _mm_mul_ps(w, _mm_load_ps(m + 12)));
  }
  return c;
}

// Equation 4 on (x, y, z, 1): (x', y', z', 0).
SKINSERVE_FORCE_INLINE __m128 TransformPoint(const Columns& m, __m128 x, __m128 y, __m128 z) {
  return _mm_add_ps(_mm_add_ps(_mm_mul_ps(x, m.c0), _mm_mul_ps(y, m.c1)),
                    _mm_add_ps(_mm_mul_ps(z, m.c2), m.c3));
}

// The upper 3x3 on (x, y, z, 0): (x', y', z', 0).
SKINSERVE_FORCE_INLINE __m128 TransformDirection(const Columns& m, __m128 x, __m128 y, __m128 z) {
  return _mm_add_ps(_mm_add_ps(_mm_mul_ps(x, m.c0), _mm_mul_ps(y, m.c1)), _mm_mul_ps(z, m.c2));
}

// Vertex K of a block of four: its x, y and z, each broadcast to a register, from the
// block's 12 floats held in three registers.
template <int K>
SKINSERVE_FORCE_INLINE void Splat(const __m128 (&in)[3], __m128& x, __m128& y, __m128& z) {
  constexpr int kX = 3 * K, kY = kX + 1, kZ = kX + 2;
  x = Broadcast<kX % 4>(in[kX / 4]);
  y = Broadcast<kY % 4>(in[kY / 4]);
  z = Broadcast<kZ % 4>(in[kZ / 4]);
}

// Four (x, y, z, 0) results a..d packed into three registers: x y z x | y z x y | z x y z.
SKINSERVE_FORCE_INLINE __m128 PackFirst(__m128 a, __m128 b) {
  const __m128 bx_az = _mm_shuffle_ps(b, a, _MM_SHUFFLE(2, 2, 0, 0));  // bx bx az az
  return _mm_shuffle_ps(a, bx_az, _MM_SHUFFLE(0, 2, 1, 0));            // ax ay az bx
}
SKINSERVE_FORCE_INLINE __m128 PackSecond(__m128 b, __m128 c) {
  return _mm_shuffle_ps(b, c, _MM_SHUFFLE(1, 0, 2, 1));  // by bz cx cy
}
SKINSERVE_FORCE_INLINE __m128 PackThird(__m128 c, __m128 d) {
  const __m128 cz_dx = _mm_shuffle_ps(c, d, _MM_SHUFFLE(0, 0, 2, 2));  // cz cz dx dx
  return _mm_shuffle_ps(cz_dx, d, _MM_SHUFFLE(2, 1, 2, 0));            // cz dx dy dz
}

// Vertex K of a block: blends its matrix and transforms its position (and normal, and
// tangent: one register per vertex, x y z w). Each vertex is finished before the next is
// blended, so four matrices never need registers at once.
template <int B, bool Normals, bool Tangents, int K>
SKINSERVE_FORCE_INLINE void SkinVertex(const float* columns, const uint16_t* joints,
                                       const float* weights, const __m128 (&p)[3],
                                       const __m128 (&n)[3], const __m128 (&t)[4],
                                       __m128 (&p_out)[4], __m128 (&n_out)[4], __m128 (&t_out)[4]) {
  const Columns m = Blend<B>(columns, joints + K * B, weights + K * B);
  __m128 x, y, z;
  Splat<K>(p, x, y, z);
  p_out[K] = TransformPoint(m, x, y, z);
  if constexpr (Normals) {
    Splat<K>(n, x, y, z);
    n_out[K] = TransformDirection(m, x, y, z);
  }
  if constexpr (Tangents) {
    t_out[K] = TransformDirection(m, Broadcast<0>(t[K]), Broadcast<1>(t[K]), Broadcast<2>(t[K]));
  }
}

// The inverse lengths of four transformed (x, y, z, 0) directions, one per lane.
SKINSERVE_FORCE_INLINE __m128 InverseLengths(const __m128 (&t)[4]) {
  __m128 s0 = _mm_mul_ps(t[0], t[0]), s1 = _mm_mul_ps(t[1], t[1]);
  __m128 s2 = _mm_mul_ps(t[2], t[2]), s3 = _mm_mul_ps(t[3], t[3]);
  _MM_TRANSPOSE4_PS(s0, s1, s2, s3);  // s0: the four x², s1: the y², s2: the z², s3: 0
  const __m128 length = _mm_sqrt_ps(_mm_add_ps(_mm_add_ps(s0, s1), s2));
  return _mm_div_ps(_mm_set1_ps(1.0f), length);
}

// Renormalises four transformed tangents (x, y, z, +-0), puts back the rest tangents' w
// (the fourth lane is cleared first: it may be -0, whose sign bit would flip w) and stores
// them: 16 floats at `out`.
SKINSERVE_FORCE_INLINE void StoreTangents(const __m128 (&t)[4], const __m128 (&rest)[4],
                                          float* out) {
  const __m128 inverse = InverseLengths(t);
  const __m128 w = _mm_castsi128_ps(_mm_setr_epi32(0, 0, 0, -1));
  const auto store = [&](int k, __m128 scaled) __attribute__((always_inline)) {
    _mm_storeu_ps(out + 4 * k, _mm_or_ps(_mm_andnot_ps(w, scaled), _mm_and_ps(rest[k], w)));
  };
  store(0, _mm_mul_ps(t[0], Broadcast<0>(inverse)));
  store(1, _mm_mul_ps(t[1], Broadcast<1>(inverse)));
  store(2, _mm_mul_ps(t[2], Broadcast<2>(inverse)));
  store(3, _mm_mul_ps(t[3], Broadcast<3>(inverse)));
}

// Renormalises four transformed normals and stores them: one true square root and one
// division for the four (rsqrt's 12 bits would miss the 1e-5 tolerance).
SKINSERVE_FORCE_INLINE void StoreNormalised(__m128 (&t)[4], float* out) {
  const __m128 inverse = InverseLengths(t);
  t[0] = _mm_mul_ps(t[0], Broadcast<0>(inverse));
  t[1] = _mm_mul_ps(t[1], Broadcast<1>(inverse));
  t[2] = _mm_mul_ps(t[2], Broadcast<2>(inverse));
  t[3] = _mm_mul_ps(t[3], Broadcast<3>(inverse));
  _mm_storeu_ps(out, PackFirst(t[0], t[1]));
  _mm_storeu_ps(out + 4, PackSecond(t[1], t[2]));
  _mm_storeu_ps(out + 8, PackThird(t[2], t[3]));
}

// Skins one block of four vertices: 12 floats of positions (and normals; 16 of tangents)
// in and out.
template <int B, bool Normals, bool Tangents>
SKINSERVE_FORCE_INLINE void SkinFour(const float* columns, const float* positions,
                                     const float* normals, const float* tangents,
                                     const uint16_t* joints, const float* weights,
                                     float* out_positions, float* out_normals,
                                     float* out_tangents) {
  const __m128 p[3] = {_mm_loadu_ps(positions), _mm_loadu_ps(positions + 4),
                       _mm_loadu_ps(positions + 8)};
  __m128 n[3] = {}, t[4] = {}, p_out[4], n_out[4] = {}, t_out[4] = {};
  if constexpr (Normals) {
    n[0] = _mm_loadu_ps(normals), n[1] = _mm_loadu_ps(normals + 4);
    n[2] = _mm_loadu_ps(normals + 8);
  }
  if constexpr (Tangents) {
    t[0] = _mm_loadu_ps(tangents), t[1] = _mm_loadu_ps(tangents + 4);
    t[2] = _mm_loadu_ps(tangents + 8), t[3] = _mm_loadu_ps(tangents + 12);
  }
  SkinVertex<B, Normals, Tangents, 0>(columns, joints, weights, p, n, t, p_out, n_out, t_out);
  SkinVertex<B, Normals, Tangents, 1>(columns, joints, weights, p, n, t, p_out, n_out, t_out);
  _mm_storeu_ps(out_positions, PackFirst(p_out[0], p_out[1]));
  SkinVertex<B, Normals, Tangents, 2>(columns, joints, weights, p, n, t, p_out, n_out, t_out);
  _mm_storeu_ps(out_positions + 4, PackSecond(p_out[1], p_out[2]));
  SkinVertex<B, Normals, Tangents, 3>(columns, joints, weights, p, n, t, p_out, n_out, t_out);
  _mm_storeu_ps(out_positions + 8, PackThird(p_out[2], p_out[3]));
  if constexpr (Normals) StoreNormalised(n_out, out_normals);
  if constexpr (Tangents) StoreTangents(t_out, t, out_tangents);
}

template <int B, bool Normals, bool Tangents>
void SkinSseRange(const Mesh& mesh, const ColumnPalette& palette, const SkinFrame& frame,
                  std::size_t first, std::size_t last) {
  const float* columns = palette.joint(0);
  ForEachBlockOfFour<B, Normals, Tangents>(
      mesh, frame, first, last,
      [&](const float* p, const float* n, const float* t, const uint16_t* j, const float* w,
          float* rp, float* rn, float* rt) __attribute__((always_inline)) {
        SkinFour<B, Normals, Tangents>(columns, p, n, t, j, w, rp, rn, rt);
      });
}

// The kernel of CpuBackend (cpu_backend.h): the frame's ColumnPalette, SkinSseRange<B,
// normals, tangents> for the mesh's B (1..8).
struct SseKernel {
  using FramePalette = ColumnPalette;
  static void SkinRange(const Mesh& mesh, const FramePalette& palette, const SkinFrame& frame,
                        std::size_t first, std::size_t last) {
    WithInfluences(mesh.influences(), [&](auto b) {
      constexpr int kB = decltype(b)::value;
      if (frame.normals.empty()) {
        SkinSseRange<kB, false, false>(mesh, palette, frame, first, last);
      } else if (frame.tangents.empty()) {
        SkinSseRange<kB, true, false>(mesh, palette, frame, first, last);
      } else {
        SkinSseRange<kB, true, true>(mesh, palette, frame, first, last);
      }
    });
  }
};

}  // namespace skinserve::sse
