// The SSE skinning loop shared by `sse` and `sse-openmp`: the paper's SSE scheme. Each
// 3x4 matrix row is one __m128, so blending B joint matrices is 3 * B multiply-adds of
// whole rows, and the transform is 3 row products summed through a 4x4 transpose.
// SSE2 only (baseline x86-64): it runs on any 64-bit x86 the image runs on.
#pragma once

#include <xmmintrin.h>

#include <cstddef>
#include <cstdint>

#include "influence_dispatch.h"
#include "skinserve/core/backend.h"

namespace skinserve::sse {

// Row products r[k] * v summed horizontally: (r0.v, r1.v, r2.v, 0).
inline __m128 TransformRows(__m128 r0, __m128 r1, __m128 r2, __m128 v) {
  __m128 t0 = _mm_mul_ps(r0, v);
  __m128 t1 = _mm_mul_ps(r1, v);
  __m128 t2 = _mm_mul_ps(r2, v);
  __m128 t3 = _mm_setzero_ps();
  _MM_TRANSPOSE4_PS(t0, t1, t2, t3);
  return _mm_add_ps(_mm_add_ps(t0, t1), _mm_add_ps(t2, t3));
}

// Stores exactly three floats: never touches the next vertex, which another thread owns.
inline void Store3(float* out, __m128 xyz) {
  _mm_storel_pi(reinterpret_cast<__m64*>(out), xyz);
  _mm_store_ss(out + 2, _mm_movehl_ps(xyz, xyz));
}

template <int B>
void SkinSseRange(const Mesh& mesh, const SkinFrame& frame, std::size_t first, std::size_t last) {
  const float* palette = frame.palette.data();
  const float* positions = mesh.positions().data();
  const float* normals = mesh.normals().data();
  const uint16_t* joints = mesh.joints().data();
  const float* weights = mesh.weights().data();
  float* out_p = frame.positions.data();
  float* out_n = frame.normals.empty() ? nullptr : frame.normals.data();
  for (std::size_t v = first; v < last; ++v) {
    // Equation 3, a row at a time.
    __m128 w = _mm_set1_ps(weights[v * B]);
    const float* j = palette + 12 * joints[v * B];
    __m128 r0 = _mm_mul_ps(w, _mm_loadu_ps(j));
    __m128 r1 = _mm_mul_ps(w, _mm_loadu_ps(j + 4));
    __m128 r2 = _mm_mul_ps(w, _mm_loadu_ps(j + 8));
    for (int i = 1; i < B; ++i) {
      w = _mm_set1_ps(weights[v * B + i]);
      j = palette + 12 * joints[v * B + i];
      r0 = _mm_add_ps(r0, _mm_mul_ps(w, _mm_loadu_ps(j)));
      r1 = _mm_add_ps(r1, _mm_mul_ps(w, _mm_loadu_ps(j + 4)));
      r2 = _mm_add_ps(r2, _mm_mul_ps(w, _mm_loadu_ps(j + 8)));
    }
    // Equation 4 on (x, y, z, 1).
    const float* p = positions + 3 * v;
    Store3(out_p + 3 * v, TransformRows(r0, r1, r2, _mm_setr_ps(p[0], p[1], p[2], 1.0f)));
    if (out_n != nullptr) {
      const float* n = normals + 3 * v;
      const __m128 t = TransformRows(r0, r1, r2, _mm_setr_ps(n[0], n[1], n[2], 0.0f));
      __m128 squares = _mm_mul_ps(t, t);  // (x², y², z², 0)
      __m128 sum = _mm_add_ps(squares, _mm_movehl_ps(squares, squares));
      sum = _mm_add_ss(sum, _mm_shuffle_ps(sum, sum, _MM_SHUFFLE(1, 1, 1, 1)));
      // A true square root and division: rsqrt's 12 bits would miss the 1e-5 tolerance.
      const __m128 length = _mm_sqrt_ss(sum);
      Store3(out_n + 3 * v, _mm_div_ps(t, _mm_shuffle_ps(length, length, 0)));
    }
  }
}

inline void SkinSse(const Mesh& mesh, const SkinFrame& frame, std::size_t first, std::size_t last) {
  WithInfluences(mesh.influences(),
                 [&](auto b) { SkinSseRange<decltype(b)::value>(mesh, frame, first, last); });
}

}  // namespace skinserve::sse
