// Four floats side by side: SSE2 on x86-64 (its baseline, as ozz's SSE2 runtime; VEX
// encoded and fused in the AVX2 + FMA clones, isa_clones.h), plain arrays elsewhere. The pose jobs
// work on 4 joints or 4 tracks at a time with it (SoA).
#pragma once

#include <cmath>

#include "isa_clones.h"

#include <cstdint>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace skinserve::animation::detail {

#if defined(__SSE2__)
struct F4 {
  __m128 v;
};
SKINSERVE_ALWAYS_INLINE F4 Load4(const float* p) { return {_mm_loadu_ps(p)}; }
SKINSERVE_ALWAYS_INLINE void Store4(F4 a, float* p) { _mm_storeu_ps(p, a.v); }
SKINSERVE_ALWAYS_INLINE F4 Splat(float x) { return {_mm_set1_ps(x)}; }
SKINSERVE_ALWAYS_INLINE F4 Set4(float a, float b, float c, float d) {
  return {_mm_setr_ps(a, b, c, d)};
}
SKINSERVE_ALWAYS_INLINE F4 operator+(F4 a, F4 b) { return {_mm_add_ps(a.v, b.v)}; }
SKINSERVE_ALWAYS_INLINE F4 operator-(F4 a, F4 b) { return {_mm_sub_ps(a.v, b.v)}; }
SKINSERVE_ALWAYS_INLINE F4 operator*(F4 a, F4 b) { return {_mm_mul_ps(a.v, b.v)}; }
SKINSERVE_ALWAYS_INLINE F4 Max(F4 a, F4 b) { return {_mm_max_ps(a.v, b.v)}; }
SKINSERVE_ALWAYS_INLINE F4 Sqrt(F4 a) { return {_mm_sqrt_ps(a.v)}; }
SKINSERVE_ALWAYS_INLINE F4 Div(F4 a, F4 b) { return {_mm_div_ps(a.v, b.v)}; }
// 1 / sqrt(a) for a > 0: the 12-bit estimate and one Newton step, within 5e-7 relative
// (the step squares the estimate's 3.7e-4), a few times cheaper than a sqrt and a divide.
SKINSERVE_ALWAYS_INLINE F4 InverseSqrt(F4 a) {
  const __m128 y = _mm_rsqrt_ps(a.v);
  const __m128 ayy = _mm_mul_ps(_mm_mul_ps(a.v, y), y);
  return {_mm_mul_ps(_mm_mul_ps(_mm_set1_ps(0.5f), y), _mm_sub_ps(_mm_set1_ps(3.0f), ayy))};
}
// -1 where a < 0, else 1.
SKINSERVE_ALWAYS_INLINE F4 SignOf(F4 a) {
  const __m128 negative = _mm_and_ps(a.v, _mm_set1_ps(-0.0f));
  return {_mm_or_ps(_mm_set1_ps(1.0f), negative)};
}
// True when every lane of a is greater than b.
SKINSERVE_ALWAYS_INLINE bool AllGreater(F4 a, F4 b) {
  return _mm_movemask_ps(_mm_cmpgt_ps(a.v, b.v)) == 0xf;
}
// Lane i of x, y, z, w becomes row i (a 4x4 transpose): SoA to AoS.
SKINSERVE_ALWAYS_INLINE void Transpose(F4& x, F4& y, F4& z, F4& w) {
  _MM_TRANSPOSE4_PS(x.v, y.v, z.v, w.v);
}
// Per lane: a where a == b lanes hold (m), else b.
SKINSERVE_ALWAYS_INLINE F4 Equal(F4 a, F4 b) { return {_mm_cmpeq_ps(a.v, b.v)}; }
SKINSERVE_ALWAYS_INLINE F4 Select(F4 m, F4 a, F4 b) {
  return {_mm_or_ps(_mm_and_ps(m.v, a.v), _mm_andnot_ps(m.v, b.v))};
}
SKINSERVE_ALWAYS_INLINE F4 Broadcast(const float* p) { return {_mm_set1_ps(*p)}; }
// a . b in every lane.
SKINSERVE_ALWAYS_INLINE F4 Dot(F4 a, F4 b) {
  const __m128 m = _mm_mul_ps(a.v, b.v);
  const __m128 pairs = _mm_add_ps(m, _mm_shuffle_ps(m, m, _MM_SHUFFLE(2, 3, 0, 1)));
  return {_mm_add_ps(pairs, _mm_shuffle_ps(pairs, pairs, _MM_SHUFFLE(1, 0, 3, 2)))};
}
// -a where d < 0, else a, per lane.
SKINSERVE_ALWAYS_INLINE F4 NegateWhereNegative(F4 a, F4 d) {
  const __m128 negative = _mm_cmplt_ps(d.v, _mm_setzero_ps());
  return {_mm_xor_ps(a.v, _mm_and_ps(negative, _mm_set1_ps(-0.0f)))};
}
// Lane `lane` of a in every lane.
template <int lane>
SKINSERVE_ALWAYS_INLINE F4 SplatLane(F4 a) {
  return {_mm_shuffle_ps(a.v, a.v, _MM_SHUFFLE(lane, lane, lane, lane))};
}
// (0, 0, 0, a's lane 3).
SKINSERVE_ALWAYS_INLINE F4 KeepLane3(F4 a) {
  return {_mm_and_ps(a.v, _mm_castsi128_ps(_mm_setr_epi32(0, 0, 0, -1)))};
}
// p[0..3] as floats.
SKINSERVE_ALWAYS_INLINE F4 LoadU16x4(const uint16_t* p) {
  const __m128i q = _mm_loadl_epi64(reinterpret_cast<const __m128i*>(p));
  return {_mm_cvtepi32_ps(_mm_unpacklo_epi16(q, _mm_setzero_si128()))};
}
// p[0..2] as floats, lane 3 zero, read as p[-1..2] (p[-1] must be readable: no read past
// p[2]).
SKINSERVE_ALWAYS_INLINE F4 LoadU16x3(const uint16_t* p) {
  const __m128i q = _mm_srli_si128(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(p - 1)), 2);
  return {_mm_cvtepi32_ps(_mm_unpacklo_epi16(q, _mm_setzero_si128()))};
}
#else
struct F4 {
  float v[4];
};
SKINSERVE_ALWAYS_INLINE F4 Load4(const float* p) { return {{p[0], p[1], p[2], p[3]}}; }
SKINSERVE_ALWAYS_INLINE void Store4(F4 a, float* p) {
  for (int i = 0; i < 4; ++i) p[i] = a.v[i];
}
SKINSERVE_ALWAYS_INLINE F4 Splat(float x) { return {{x, x, x, x}}; }
SKINSERVE_ALWAYS_INLINE F4 Set4(float a, float b, float c, float d) { return {{a, b, c, d}}; }
#define SKINSERVE_F4_OP(name, expr)              \
  inline F4 name(F4 a, F4 b) {                   \
    F4 r;                                        \
    for (int i = 0; i < 4; ++i) r.v[i] = (expr); \
    return r;                                    \
  }
SKINSERVE_F4_OP(operator+, a.v[i] + b.v[i])
SKINSERVE_F4_OP(operator-, a.v[i] - b.v[i])
SKINSERVE_F4_OP(operator*, a.v[i] * b.v[i])
SKINSERVE_F4_OP(Max, a.v[i] > b.v[i] ? a.v[i] : b.v[i])
SKINSERVE_F4_OP(Div, a.v[i] / b.v[i])
#undef SKINSERVE_F4_OP
SKINSERVE_ALWAYS_INLINE F4 Sqrt(F4 a) {
  for (float& x : a.v) x = std::sqrt(x);
  return a;
}
SKINSERVE_ALWAYS_INLINE F4 SignOf(F4 a) {
  for (float& x : a.v) x = std::signbit(x) ? -1.0f : 1.0f;
  return a;
}
SKINSERVE_ALWAYS_INLINE F4 InverseSqrt(F4 a) {
  for (float& x : a.v) x = 1.0f / std::sqrt(x);
  return a;
}
SKINSERVE_ALWAYS_INLINE bool AllGreater(F4 a, F4 b) {
  for (int i = 0; i < 4; ++i) {
    if (!(a.v[i] > b.v[i])) return false;
  }
  return true;
}
SKINSERVE_ALWAYS_INLINE void Transpose(F4& x, F4& y, F4& z, F4& w) {
  F4* rows[4] = {&x, &y, &z, &w};
  for (int r = 0; r < 4; ++r) {
    for (int c = r + 1; c < 4; ++c) {
      const float t = rows[r]->v[c];
      rows[r]->v[c] = rows[c]->v[r];
      rows[c]->v[r] = t;
    }
  }
}
SKINSERVE_ALWAYS_INLINE F4 Broadcast(const float* p) { return Splat(*p); }
SKINSERVE_ALWAYS_INLINE F4 Dot(F4 a, F4 b) {
  return Splat(a.v[0] * b.v[0] + a.v[1] * b.v[1] + a.v[2] * b.v[2] + a.v[3] * b.v[3]);
}
SKINSERVE_ALWAYS_INLINE F4 NegateWhereNegative(F4 a, F4 d) {
  for (int i = 0; i < 4; ++i) a.v[i] = d.v[i] < 0 ? -a.v[i] : a.v[i];
  return a;
}
SKINSERVE_ALWAYS_INLINE F4 LoadU16x4(const uint16_t* p) { return Set4(p[0], p[1], p[2], p[3]); }
template <int lane>
SKINSERVE_ALWAYS_INLINE F4 SplatLane(F4 a) {
  return Splat(a.v[lane]);
}
SKINSERVE_ALWAYS_INLINE F4 KeepLane3(F4 a) { return Set4(0, 0, 0, a.v[3]); }
SKINSERVE_ALWAYS_INLINE F4 LoadU16x3(const uint16_t* p) { return Set4(p[0], p[1], p[2], 0); }
SKINSERVE_ALWAYS_INLINE F4 Equal(F4 a, F4 b) {
  for (int i = 0; i < 4; ++i) a.v[i] = a.v[i] == b.v[i] ? 1.0f : 0.0f;
  return a;
}
SKINSERVE_ALWAYS_INLINE F4 Select(F4 m, F4 a, F4 b) {
  for (int i = 0; i < 4; ++i) a.v[i] = m.v[i] != 0 ? a.v[i] : b.v[i];
  return a;
}
#endif

}  // namespace skinserve::animation::detail
