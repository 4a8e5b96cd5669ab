// See vertex_encoding_kernels.h. x y z triples are interleaved, so a vector of N lanes
// (N a power of two, never a multiple of 3) meets the axes in a pattern that repeats every
// three vectors: the loops take 3N values (N vertices) at a time, each of the three vectors
// with its own per-axis constants (lane l of vector k holds axis (kN + l) % 3). The last
// values (fewer than 3N) go through the same formulas one at a time.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "vertex_encoding_kernels.cpp"
// SSSE3 would add compile time and nothing over SSE4 on any CPU we run on.
#ifndef HWY_DISABLED_TARGETS
#define HWY_DISABLED_TARGETS HWY_SSSE3
#endif
#include <hwy/foreach_target.h>  // IWYU pragma: keep
// Order matters: foreach_target.h first, then highway.h.
#include <hwy/highway.h>

#include <cmath>
#include <cstring>

#include "vertex_encoding_kernels.h"

HWY_BEFORE_NAMESPACE();
namespace skinserve::encoding_kernels {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

using D = hn::ScalableTag<float>;
using DI = hn::RebindToSigned<D>;
using D16 = hn::Rebind<int16_t, D>;
using V = hn::Vec<D>;
constexpr std::size_t kMaxLanes = HWY_MAX_BYTES / sizeof(float);
constexpr float kSnorm16Max = 32767.0f;
constexpr float kInvSnorm16Max = 1.0f / kSnorm16Max;

// The three vectors of per-axis constants for a block: per_axis[a] at every lane of axis a.
// (Vectors of SVE targets are sizeless: no arrays of them, hence three outputs.)
HWY_INLINE void AxisPattern(D d, const float* per_axis, V* v0, V* v1, V* v2) {
  const std::size_t n = hn::Lanes(d);
  HWY_ALIGN float pattern[3 * kMaxLanes];
  for (std::size_t i = 0; i < 3 * n; ++i) pattern[i] = per_axis[i % 3];
  *v0 = hn::Load(d, pattern);
  *v1 = hn::Load(d, pattern + n);
  *v2 = hn::Load(d, pattern + 2 * n);
}

inline int16_t RoundClamped(float t) {
  // Written so that NaN clamps too (the caller refuses it): NaN to integer is undefined.
  const float clamped = t >= -kSnorm16Max ? (t <= kSnorm16Max ? t : kSnorm16Max) : -kSnorm16Max;
  return static_cast<int16_t>(std::nearbyint(clamped));  // to nearest even
}

inline void StoreS16(int16_t value, void* out, std::size_t i) {
  std::memcpy(static_cast<char*>(out) + 2 * i, &value, 2);
}
inline int16_t LoadS16(const void* in, std::size_t i) {
  int16_t value;
  std::memcpy(&value, static_cast<const char*>(in) + 2 * i, 2);
  return value;
}

HWY_INLINE void BoundsStep(V x, V* lo, V* hi, V* poison) {
  *lo = hn::Min(*lo, x);
  *hi = hn::Max(*hi, x);
  // x - x is +0 (no bit set) for finite x and NaN otherwise; OR keeps any NaN a NaN, and
  // costs one cycle on the loop's carried chain where an add would cost four.
  *poison = hn::Or(*poison, hn::Sub(x, x));
}

bool Bounds(const float* HWY_RESTRICT in, std::size_t n, float* lo, float* hi) {
  const D d;
  const std::size_t lanes = hn::Lanes(d);
  for (int a = 0; a < 3; ++a) lo[a] = hi[a] = in[a];
  V lo0, lo1, lo2;
  AxisPattern(d, lo, &lo0, &lo1, &lo2);
  V hi0 = lo0, hi1 = lo1, hi2 = lo2;
  V poison = hn::Zero(d);
  std::size_t i = 0;
  for (; i + 3 * lanes <= n; i += 3 * lanes) {
    BoundsStep(hn::LoadU(d, in + i), &lo0, &hi0, &poison);
    BoundsStep(hn::LoadU(d, in + i + lanes), &lo1, &hi1, &poison);
    BoundsStep(hn::LoadU(d, in + i + 2 * lanes), &lo2, &hi2, &poison);
  }
  HWY_ALIGN float lanes_lo[3 * kMaxLanes], lanes_hi[3 * kMaxLanes];
  hn::Store(lo0, d, lanes_lo);
  hn::Store(lo1, d, lanes_lo + lanes);
  hn::Store(lo2, d, lanes_lo + 2 * lanes);
  hn::Store(hi0, d, lanes_hi);
  hn::Store(hi1, d, lanes_hi + lanes);
  hn::Store(hi2, d, lanes_hi + 2 * lanes);
  bool finite = hn::AllTrue(d, hn::Eq(poison, hn::Zero(d)));
  for (std::size_t k = 0; k < 3 * lanes; ++k) {
    lo[k % 3] = std::fmin(lo[k % 3], lanes_lo[k]);
    hi[k % 3] = std::fmax(hi[k % 3], lanes_hi[k]);
  }
  for (; i < n; ++i) {
    lo[i % 3] = std::fmin(lo[i % 3], in[i]);
    hi[i % 3] = std::fmax(hi[i % 3], in[i]);
    finite = finite && std::isfinite(in[i]);
  }
  return finite;  // in[0..2] are in the first block or in the tail: both checked
}

// One vector of positions: returns `inside` narrowed by this vector's check.
HWY_INLINE V EncodePositionVector(D d, const float* HWY_RESTRICT in, V centre, V scale, V lo, V hi,
                                  V inside, int16_t* out) {
  const D16 d16;
  const V x = hn::LoadU(d, in);
  const V limit = hn::Set(d, kSnorm16Max);
  const V t = hn::Min(hn::Max(hn::Mul(hn::Sub(x, centre), scale), hn::Neg(limit)), limit);
  hn::StoreU(hn::DemoteTo(d16, hn::NearestInt(t)), d16, out);
  return hn::And(inside, hn::VecFromMask(d, hn::And(hn::Ge(x, lo), hn::Le(x, hi))));
}

bool EncodeSnorm16Positions(const float* HWY_RESTRICT in, std::size_t n, const float* centre,
                            const float* scale, const float* lo, const float* hi, void* out) {
  const D d;
  const std::size_t lanes = hn::Lanes(d);
  V c0, c1, c2, s0, s1, s2, l0, l1, l2, h0, h1, h2;
  AxisPattern(d, centre, &c0, &c1, &c2);
  AxisPattern(d, scale, &s0, &s1, &s2);
  AxisPattern(d, lo, &l0, &l1, &l2);
  AxisPattern(d, hi, &h0, &h1, &h2);
  auto* o = static_cast<int16_t*>(out);
  V inside = hn::VecFromMask(d, hn::Eq(hn::Zero(d), hn::Zero(d)));
  std::size_t i = 0;
  for (; i + 3 * lanes <= n; i += 3 * lanes) {
    inside = EncodePositionVector(d, in + i, c0, s0, l0, h0, inside, o + i);
    inside = EncodePositionVector(d, in + i + lanes, c1, s1, l1, h1, inside, o + i + lanes);
    inside = EncodePositionVector(d, in + i + 2 * lanes, c2, s2, l2, h2, inside, o + i + 2 * lanes);
  }
  bool ok = hn::AllTrue(d, hn::MaskFromVec(inside));
  for (; i < n; ++i) {
    const std::size_t a = i % 3;
    ok = ok && in[i] >= lo[a] && in[i] <= hi[a];
    StoreS16(RoundClamped((in[i] - centre[a]) * scale[a]), out, i);
  }
  return ok;
}

HWY_INLINE void DecodePositionVector(D d, const int16_t* in, V centre, V half_extent,
                                     float* HWY_RESTRICT out) {
  const D16 d16;
  const DI di;
  const V q = hn::ConvertTo(d, hn::PromoteTo(di, hn::LoadU(d16, in)));
  hn::StoreU(hn::Add(centre, hn::Mul(hn::Mul(q, hn::Set(d, kInvSnorm16Max)), half_extent)), d, out);
}

void DecodeSnorm16Positions(const void* in, std::size_t n, const float* centre,
                            const float* half_extent, float* HWY_RESTRICT out) {
  const D d;
  const std::size_t lanes = hn::Lanes(d);
  V c0, c1, c2, h0, h1, h2;
  AxisPattern(d, centre, &c0, &c1, &c2);
  AxisPattern(d, half_extent, &h0, &h1, &h2);
  const auto* q = static_cast<const int16_t*>(in);
  std::size_t i = 0;
  for (; i + 3 * lanes <= n; i += 3 * lanes) {
    DecodePositionVector(d, q + i, c0, h0, out + i);
    DecodePositionVector(d, q + i + lanes, c1, h1, out + i + lanes);
    DecodePositionVector(d, q + i + 2 * lanes, c2, h2, out + i + 2 * lanes);
  }
  for (; i < n; ++i) {
    out[i] =
        centre[i % 3] + (static_cast<float>(LoadS16(in, i)) * kInvSnorm16Max) * half_extent[i % 3];
  }
}

bool EncodeSnorm16Normals(const float* HWY_RESTRICT in, std::size_t n, void* out) {
  const D d;
  const D16 d16;
  const std::size_t lanes = hn::Lanes(d);
  constexpr float kLimit = 32767.5f;  // |n * 32767| below this rounds into [-32767, 32767]
  const V scale = hn::Set(d, kSnorm16Max);
  const V limit = hn::Set(d, kLimit);
  auto* o = static_cast<int16_t*>(out);
  V good = hn::VecFromMask(d, hn::Eq(hn::Zero(d), hn::Zero(d)));
  std::size_t i = 0;
  for (; i + lanes <= n; i += lanes) {
    const V t = hn::Mul(hn::LoadU(d, in + i), scale);
    good = hn::And(good, hn::VecFromMask(d, hn::Lt(hn::Abs(t), limit)));
    const V clamped = hn::Min(hn::Max(t, hn::Neg(scale)), scale);
    hn::StoreU(hn::DemoteTo(d16, hn::NearestInt(clamped)), d16, o + i);
  }
  bool ok = hn::AllTrue(d, hn::MaskFromVec(good));
  for (; i < n; ++i) {
    const float t = in[i] * kSnorm16Max;
    ok = ok && std::fabs(t) < kLimit;
    StoreS16(RoundClamped(t), out, i);
  }
  return ok;
}

void DecodeSnorm16Normals(const void* in, std::size_t n, float* HWY_RESTRICT out) {
  const D d;
  const D16 d16;
  const DI di;
  const std::size_t lanes = hn::Lanes(d);
  const auto* q = static_cast<const int16_t*>(in);
  const V inverse = hn::Set(d, kInvSnorm16Max);
  std::size_t i = 0;
  for (; i + lanes <= n; i += lanes) {
    hn::StoreU(hn::Mul(hn::ConvertTo(d, hn::PromoteTo(di, hn::LoadU(d16, q + i))), inverse), d,
               out + i);
  }
  for (; i < n; ++i) out[i] = static_cast<float>(LoadS16(in, i)) * kInvSnorm16Max;
}

}  // namespace HWY_NAMESPACE
}  // namespace skinserve::encoding_kernels
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace skinserve::encoding_kernels {

HWY_EXPORT(Bounds);
HWY_EXPORT(EncodeSnorm16Positions);
HWY_EXPORT(DecodeSnorm16Positions);
HWY_EXPORT(EncodeSnorm16Normals);
HWY_EXPORT(DecodeSnorm16Normals);

bool Bounds(const float* in, std::size_t n, float* lo, float* hi) {
  return HWY_DYNAMIC_DISPATCH(Bounds)(in, n, lo, hi);
}

bool EncodeSnorm16Positions(const float* in, std::size_t n, const float* centre, const float* scale,
                            const float* lo, const float* hi, void* out) {
  return HWY_DYNAMIC_DISPATCH(EncodeSnorm16Positions)(in, n, centre, scale, lo, hi, out);
}

void DecodeSnorm16Positions(const void* in, std::size_t n, const float* centre,
                            const float* half_extent, float* out) {
  HWY_DYNAMIC_DISPATCH(DecodeSnorm16Positions)(in, n, centre, half_extent, out);
}

bool EncodeSnorm16Normals(const float* in, std::size_t n, void* out) {
  return HWY_DYNAMIC_DISPATCH(EncodeSnorm16Normals)(in, n, out);
}

void DecodeSnorm16Normals(const void* in, std::size_t n, float* out) {
  HWY_DYNAMIC_DISPATCH(DecodeSnorm16Normals)(in, n, out);
}

}  // namespace skinserve::encoding_kernels
#endif  // HWY_ONCE
