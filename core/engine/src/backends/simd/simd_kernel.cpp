// The `simd` skinning kernel, written once with Google Highway and compiled for every
// target the build allows (x86: SCALAR, SSE4, AVX2, AVX3; Arm: NEON, SVE, SVE2 and their
// 128/256-bit specialisations); the baseline stays plain x86-64 (or arm64) and
// SelectKernel() picks the best target the CPU runs.
//
// Per vertex: the blended matrix is B multiply-adds of whole palette records (a joint's
// 16 floats are one 512-bit, two 256-bit or four 128-bit vectors, so every lane works),
// then (x, y, z, 1) times its four columns, summed to one 128-bit (x', y', z', 0).
// Results are stored 4 floats at a time at 3-float steps: each store's fourth float is
// overwritten by the next vertex, and the last vertex of a range goes through a local
// copy so nothing outside the range is touched. Normals are renormalised a chunk at a
// time, a vector of vertices per step (InverseLength: an estimate and a Newton step), while
// the chunk is still in L1. Tangents (4 floats per
// vertex) take the normals' path in the same loop: their stores of (x', y', z', 0) fill
// exactly one vertex, and the renormalising step puts back the rest tangents' w.
// On 16-lane targets (AVX-512) most vertices go four at a time instead (SkinFour): the
// four blended matrices transposed by blocks, three multiply-adds per output for all four,
// one 16-float store.
// The quantized rest stream takes the same blend and transform, each vertex's integer
// position converted in registers and the weights decoded a 256-vertex chunk at a time into
// an L1 scratch (SkinQuantizedRangeT).
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "backends/simd/simd_kernel.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include "backends/simd/simd_kernel_targets.h"
// Order matters: foreach_target.h first, then highway.h.
#include <hwy/highway.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <type_traits>

#include "backends/common/influence_dispatch.h"
#include "backends/simd/simd_stream.h"

HWY_BEFORE_NAMESPACE();
namespace skinserve::simd {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// SVE's vectors are sizeless: they cannot live in arrays or structs, so those targets
// take the 128-bit path below with the four columns in locals (the first 128 bits of
// each vector, whatever its length).
#define SKINSERVE_SIMD_SIZELESS \
  ((HWY_TARGET & (HWY_SVE | HWY_SVE2 | HWY_SVE_256 | HWY_SVE2_128)) != 0)
#if SKINSERVE_SIMD_SIZELESS
using D = hn::FixedTag<float, 4>;
#else
using D = hn::CappedTag<float, kFloatsPerJoint>;  // at most one palette record
#endif
using V = hn::Vec<D>;
constexpr std::size_t kLanes = hn::MaxLanes(D());
constexpr std::size_t kVectorsPerJoint = kFloatsPerJoint / kLanes;
static_assert(kLanes == 1 || (kLanes >= 4 && kFloatsPerJoint % kLanes == 0),
              "HWY_SCALAR, or 4, 8 or 16 float lanes");
// HWY_SCALAR (the fallback of x86-64 CPUs without SSE4: GCC 12.2 has no EMU128) has one
// lane; every other target has 128-bit vectors for one vertex's (x', y', z', 0).
#if HWY_TARGET != HWY_SCALAR
using D4 = hn::FixedTag<float, 4>;
using V4 = hn::Vec<D4>;
#endif

#if SKINSERVE_SIMD_SIZELESS
struct Spread {};

// Column k of the blended matrix (equation 3, as Blend() below): 4 lanes.
template <int B, typename Joint>
HWY_INLINE V BlendColumn(const float* HWY_RESTRICT columns, const Joint* HWY_RESTRICT joints,
                         const float* HWY_RESTRICT weights, std::size_t k) {
  const D d;
  const V base = hn::Load(d, columns + kFloatsPerJoint * joints[B - 1] + 4 * k);
  V sum = base;
  for (int i = 0; i < B - 1; ++i) {
    const float* record = columns + kFloatsPerJoint * joints[i];
    sum = hn::MulAdd(hn::Set(d, weights[i]), hn::Sub(hn::Load(d, record + 4 * k), base), sum);
  }
  return sum;
}

// One vertex: 4 floats stored at each output (the fourth is scratch, see the top).
template <int B, bool Normals, bool Tangents, typename Joint>
HWY_INLINE void SkinVertex(const float* HWY_RESTRICT columns, const Spread&,
                           const float* HWY_RESTRICT p, const float* HWY_RESTRICT n,
                           const float* HWY_RESTRICT t, const Joint* HWY_RESTRICT joints,
                           const float* HWY_RESTRICT weights, float* HWY_RESTRICT out_p,
                           float* HWY_RESTRICT out_n, float* HWY_RESTRICT out_t) {
  const D d;
  const V c0 = BlendColumn<B>(columns, joints, weights, 0);
  const V c1 = BlendColumn<B>(columns, joints, weights, 1);
  const V c2 = BlendColumn<B>(columns, joints, weights, 2);
  const V c3 = BlendColumn<B>(columns, joints, weights, 3);
  const V xc = hn::MulAdd(c0, hn::Set(d, p[0]), c3);
  hn::StoreU(hn::MulAdd(c2, hn::Set(d, p[2]), hn::MulAdd(c1, hn::Set(d, p[1]), xc)), d, out_p);
  if constexpr (Normals) {
    const V nx = hn::Mul(c0, hn::Set(d, n[0]));
    hn::StoreU(hn::MulAdd(c2, hn::Set(d, n[2]), hn::MulAdd(c1, hn::Set(d, n[1]), nx)), d, out_n);
  }
  if constexpr (Tangents) {
    const V tx = hn::Mul(c0, hn::Set(d, t[0]));
    hn::StoreU(hn::MulAdd(c2, hn::Set(d, t[2]), hn::MulAdd(c1, hn::Set(d, t[1]), tx)), d, out_t);
  }
}
#else
struct Blended {
  // Declared here so it is compiled for this target (NEON's vectors refuse an implicit one).
  Blended() {}
  V v[kVectorsPerJoint];  // the blended matrix's four columns, flat
};

// Equation 3 with the last weight 1 - the others: M_last + sum over i < B - 1 of
// w_i (M_i - M_last). The differences go to the adders, which are otherwise idle, and
// every weight is broadcast straight from memory: the multipliers, the bottleneck, do
// B - 1 multiply-adds per record vector instead of B.
template <int B, typename Joint>
HWY_INLINE Blended Blend(const float* HWY_RESTRICT columns, const Joint* HWY_RESTRICT joints,
                         const float* HWY_RESTRICT weights) {
  const D d;
  Blended m;
  const float* last = columns + kFloatsPerJoint * joints[B - 1];
  for (std::size_t k = 0; k < kVectorsPerJoint; ++k) {
    const V base = hn::Load(d, last + k * kLanes);
    V sum = base;
    for (int i = 0; i < B - 1; ++i) {
      const float* record = columns + kFloatsPerJoint * joints[i];
      sum =
          hn::MulAdd(hn::Set(d, weights[i]), hn::Sub(hn::Load(d, record + k * kLanes), base), sum);
    }
    m.v[k] = sum;
  }
  return m;
}

#if HWY_TARGET == HWY_SCALAR
struct Spread {};

// HWY_SCALAR: one vector per float of the blended matrix.
template <bool Point>
HWY_INLINE void Transform(const Blended& m, const Spread&, const float* HWY_RESTRICT p,
                          float* HWY_RESTRICT out) {
  float c[kFloatsPerJoint];
  for (std::size_t k = 0; k < kFloatsPerJoint; ++k) c[k] = hn::GetLane(m.v[k]);
  for (int r = 0; r < 3; ++r) {
    out[r] = c[r] * p[0] + c[4 + r] * p[1] + c[8 + r] * p[2] + (Point ? c[12 + r] : 0.0f);
  }
  out[3] = 0.0f;
}
#else
// Constants of one range, built once: the lane tables that spread (x, y, z, h) over the
// column blocks.
struct Spread {
  V keep_xyz;  // 1 1 1 0 per 128-bit block
  V unit_w;    // 0 0 0 1 per 128-bit block
  using Indices = decltype(hn::SetTableIndices(D(), static_cast<const int32_t*>(nullptr)));
  Indices first;
  Indices second;  // the transform from a register, 8 lanes
  Spread() {
    const D d;
    alignas(16) static constexpr float kKeep[4] = {1, 1, 1, 0};
    alignas(16) static constexpr float kUnit[4] = {0, 0, 0, 1};
    keep_xyz = hn::LoadDup128(d, kKeep);
    unit_w = hn::LoadDup128(d, kUnit);
    alignas(64) static constexpr int32_t kFirst[16] = {0, 0, 0, 0, 1, 1, 1, 1,
                                                       2, 2, 2, 2, 3, 3, 3, 3};
    first = hn::SetTableIndices(d, kFirst);
    alignas(64) static constexpr int32_t kSecond[16] = {2, 2, 2, 2, 3, 3, 3, 3,
                                                        2, 2, 2, 2, 3, 3, 3, 3};
    second = hn::SetTableIndices(d, kSecond);
  }
};

// Equation 4: the matrix times (x, y, z, h) with h = 1 for points and 0 for directions.
// `p` must have 4 readable floats (the fourth is ignored).
// (Templated on the tag so that only the branch of this target's width is compiled.)
template <bool Point, class DD>
HWY_INLINE V4 TransformQuad(DD d, const hn::Vec<DD>* HWY_RESTRICT m, const Spread& s,
                            const float* HWY_RESTRICT p) {
  constexpr std::size_t kN = hn::MaxLanes(DD());
  if constexpr (kN == 4) {
    const auto x = hn::Set(d, p[0]), y = hn::Set(d, p[1]), z = hn::Set(d, p[2]);
    const auto xc = Point ? hn::MulAdd(m[0], x, m[3]) : hn::Mul(m[0], x);
    return hn::MulAdd(m[2], z, hn::MulAdd(m[1], y, xc));
  } else {
    const hn::Half<DD> dh;
    if constexpr (kN == 8) {
      // (x x x x y y y y) and (z z z z h h h h): broadcasts from memory and two blends,
      // which leave the multipliers and the shuffle unit alone.
      const auto first = hn::ConcatUpperLower(d, hn::Set(d, p[1]), hn::Set(d, p[0]));
      const auto second =
          hn::ConcatUpperLower(d, hn::Set(d, Point ? 1.0f : 0.0f), hn::Set(d, p[2]));
      const auto product = hn::MulAdd(m[1], second, hn::Mul(m[0], first));
      return hn::Add(hn::LowerHalf(dh, product), hn::UpperHalf(dh, product));
    } else {
      const auto xyz = hn::LoadDup128(d, p);
      const auto xyzh = Point ? hn::MulAdd(xyz, s.keep_xyz, s.unit_w) : hn::Mul(xyz, s.keep_xyz);
      const auto product = hn::Mul(m[0], hn::TableLookupLanes(xyzh, s.first));
      const auto sum8 = hn::Add(hn::LowerHalf(dh, product), hn::UpperHalf(dh, product));
      const hn::Half<hn::Half<DD>> dq;
      return hn::Add(hn::LowerHalf(dq, sum8), hn::UpperHalf(dq, sum8));
    }
  }
}

template <bool Point>
HWY_INLINE void Transform(const Blended& m, const Spread& s, const float* HWY_RESTRICT p,
                          float* HWY_RESTRICT out) {
  hn::StoreU(TransformQuad<Point>(D(), m.v, s, p), D4(), out);
}
#endif  // HWY_TARGET == HWY_SCALAR

// One vertex: 4 floats stored at each output (the fourth is scratch, see the top).
template <int B, bool Normals, bool Tangents, typename Joint>
HWY_INLINE void SkinVertex(const float* HWY_RESTRICT columns, const Spread& s,
                           const float* HWY_RESTRICT p, const float* HWY_RESTRICT n,
                           const float* HWY_RESTRICT t, const Joint* HWY_RESTRICT joints,
                           const float* HWY_RESTRICT weights, float* HWY_RESTRICT out_p,
                           float* HWY_RESTRICT out_n, float* HWY_RESTRICT out_t) {
  const Blended m = Blend<B>(columns, joints, weights);
  Transform<true>(m, s, p, out_p);
  if constexpr (Normals) Transform<false>(m, s, n, out_n);
  if constexpr (Tangents) Transform<false>(m, s, t, out_t);
}
#endif  // SKINSERVE_SIMD_SIZELESS

// Four vertices at a time on the 16-lane targets (AVX-512). Per vertex, Transform's product
// and its sum of four 128-bit blocks cost three cross-block moves and an overlapping store
// per output, which bound the loop (perf: the block sums and stores took most of its
// samples). Here four vertices' blended matrices are transposed by blocks once (column k of
// vertex i in block i: 8 block moves for 4 vertices, shared by positions and normals), each
// input is spread by one permute from its 12 packed floats, and three multiply-adds give the
// four vertices' outputs in one register, packed to 12 floats by a permute: one 16-float
// store, whose last 4 floats the next vertices overwrite. Normals keep their renormalising
// pass over the chunk: renormalising them in the register (rsqrt14 and a Newton step) was
// 4-8% faster on the VM's Zen 4 but 10-30% slower on the GPU machine's Sapphire Rapids
// (docs/results/2026-11-29-simd-four-vertices-xeon).
#if !SKINSERVE_SIMD_SIZELESS && HWY_TARGET != HWY_SCALAR
template <class DD>
struct Quad {
  using Indices = decltype(hn::SetTableIndices(DD(), static_cast<const int32_t*>(nullptr)));
  Indices x, y, z;  // vertex i's x (y, z) over block i, from 4 vertices' 12 packed floats
  Indices pack;     // block i's (x, y, z) to floats 3i..3i+2
  Quad() {
    const DD d;
    alignas(64) static constexpr int32_t kX[16] = {0, 0, 0, 0, 3, 3, 3, 3, 6, 6, 6, 6, 9, 9, 9, 9};
    alignas(64) static constexpr int32_t kY[16] = {1, 1, 1, 1, 4,  4,  4,  4,
                                                   7, 7, 7, 7, 10, 10, 10, 10};
    alignas(64) static constexpr int32_t kZ[16] = {2, 2, 2, 2, 5,  5,  5,  5,
                                                   8, 8, 8, 8, 11, 11, 11, 11};
    alignas(64) static constexpr int32_t kPack[16] = {0,  1,  2,  4,  5,  6,  8,  9,
                                                      10, 12, 13, 14, 15, 15, 15, 15};
    x = hn::SetTableIndices(d, kX);
    y = hn::SetTableIndices(d, kY);
    z = hn::SetTableIndices(d, kZ);
    pack = hn::SetTableIndices(d, kPack);
  }
};

// t[k] = (column k of m[0], of m[1], of m[2], of m[3]), one per 128-bit block.
template <class DD>
HWY_INLINE void TransposeBlocks(DD d, const hn::Vec<DD>* HWY_RESTRICT m,
                                hn::Vec<DD>* HWY_RESTRICT t) {
  // (m0 b0, m1 b0, m0 b2, m1 b2) and (m0 b1, m1 b1, m0 b3, m1 b3), and the same of m2, m3.
  const auto even01 = hn::OddEvenBlocks(hn::SwapAdjacentBlocks(m[1]), m[0]);
  const auto odd01 = hn::OddEvenBlocks(m[1], hn::SwapAdjacentBlocks(m[0]));
  const auto even23 = hn::OddEvenBlocks(hn::SwapAdjacentBlocks(m[3]), m[2]);
  const auto odd23 = hn::OddEvenBlocks(m[3], hn::SwapAdjacentBlocks(m[2]));
  t[0] = hn::ConcatLowerLower(d, even23, even01);
  t[1] = hn::ConcatLowerLower(d, odd23, odd01);
  t[2] = hn::ConcatUpperUpper(d, even23, even01);
  t[3] = hn::ConcatUpperUpper(d, odd23, odd01);
}

// Equation 4 for four vertices: vertex i's (x', y', z', 0) in block i, from their packed
// (x, y, z) in the first 12 lanes of `in`.
template <bool Point, class DD>
HWY_INLINE hn::Vec<DD> TransformFour(const hn::Vec<DD>* HWY_RESTRICT t, const Quad<DD>& q,
                                     hn::Vec<DD> in) {
  const auto x = hn::TableLookupLanes(in, q.x);
  const auto xc = Point ? hn::MulAdd(t[0], x, t[3]) : hn::Mul(t[0], x);
  return hn::MulAdd(t[2], hn::TableLookupLanes(in, q.z),
                    hn::MulAdd(t[1], hn::TableLookupLanes(in, q.y), xc));
}

// Vertices v..v+3: `p` and `n` their packed positions and normals (12 floats each), joints
// and weights theirs; 16 floats are stored at out_p and out_n (the last 4 belong to the
// next vertices), tangents per vertex as SkinVertex stores them.
template <int B, bool Normals, bool Tangents, typename Joint, class DD>
HWY_INLINE void SkinFour(DD d, const float* HWY_RESTRICT columns, const Spread& s,
                         const Quad<DD>& q, hn::Vec<DD> p, hn::Vec<DD> n,
                         const float* HWY_RESTRICT tangents, const Joint* HWY_RESTRICT joints,
                         const float* HWY_RESTRICT weights, float* HWY_RESTRICT out_p,
                         float* HWY_RESTRICT out_n, float* HWY_RESTRICT out_t) {
  hn::Vec<DD> m[4], t[4];
  for (int i = 0; i < 4; ++i) {
    const Blended blended = Blend<B>(columns, joints + B * i, weights + (B - 1) * i);
    if constexpr (Tangents) Transform<false>(blended, s, tangents + 4 * i, out_t + 4 * i);
    m[i] = blended.v[0];
  }
  TransposeBlocks(d, m, t);
  hn::StoreU(hn::TableLookupLanes(TransformFour<true>(t, q, p), q.pack), d, out_p);
  if constexpr (Normals) {
    hn::StoreU(hn::TableLookupLanes(TransformFour<false>(t, q, n), q.pack), d, out_n);
  }
}

// Whether this target skins four vertices at a time.
constexpr bool kFourAtOnce = kLanes == 16;
#else
constexpr bool kFourAtOnce = false;
#endif

#if HWY_TARGET != HWY_SCALAR
// 1 / sqrt(s) per lane. On x86 the approximate reciprocal square root (14 bits on AVX-512, 12
// on SSE4 and AVX2) refined by one Newton step to about 22 bits, inside the 1e-5 tolerance:
// a multiply and four multiply-adds where a square root and a division keep the divider busy
// (on Zen 4 perf put a third of the loop on them). A vector with a length the estimate gets
// wrong (zero, denormal, infinite or NaN: a degenerate or overflowing normal) takes the exact
// 1 / sqrt(s) instead, so those normals come out exactly as before. Arm's estimate has 8 bits,
// one step short of the tolerance: Arm keeps the exact one (not measured there).
template <class DD>
HWY_INLINE hn::Vec<DD> InverseLength(DD d, hn::Vec<DD> s) {
  if constexpr (!HWY_ARCH_X86) return hn::Div(hn::Set(d, 1.0f), hn::Sqrt(s));
  const auto in_range = hn::And(hn::Ge(s, hn::Set(d, std::numeric_limits<float>::min())),
                                hn::Le(s, hn::Set(d, std::numeric_limits<float>::max())));
  if (HWY_UNLIKELY(!hn::AllTrue(d, in_range))) return hn::Div(hn::Set(d, 1.0f), hn::Sqrt(s));
  const auto y = hn::ApproximateReciprocalSqrt(s);
  const auto half_s = hn::Mul(hn::Set(d, 0.5f), s);
  return hn::Mul(y, hn::NegMulAdd(half_s, hn::Mul(y, y), hn::Set(d, 1.5f)));  // y (1.5 - s y^2 / 2)
}

// Normals [v, last) to unit length, a whole vector of vertices at a time; returns where the
// vectors stopped.
template <class DD>
HWY_INLINE std::size_t RenormaliseVectors(DD d, float* HWY_RESTRICT normals, std::size_t v,
                                          std::size_t last) {
  const std::size_t lanes = hn::Lanes(d);
  for (; v + lanes <= last; v += lanes) {
    hn::Vec<DD> x, y, z;
    hn::LoadInterleaved3(d, normals + 3 * v, x, y, z);
    const auto inverse = InverseLength(d, hn::MulAdd(x, x, hn::MulAdd(y, y, hn::Mul(z, z))));
    hn::StoreInterleaved3(hn::Mul(x, inverse), hn::Mul(y, inverse), hn::Mul(z, inverse), d,
                          normals + 3 * v);
  }
  return v;
}
#endif

// Scales normals [first, last) to unit length: a vector of vertices at a time (16 on AVX-512),
// then four, then one by one.
HWY_INLINE void Renormalise(float* HWY_RESTRICT normals, std::size_t first, std::size_t last) {
  std::size_t v = first;
#if HWY_TARGET != HWY_SCALAR
  v = RenormaliseVectors(D(), normals, v, last);
  v = RenormaliseVectors(D4(), normals, v, last);
#endif
  for (; v < last; ++v) {
    float* n = normals + 3 * v;
    const float inverse = 1.0f / std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    n[0] *= inverse, n[1] *= inverse, n[2] *= inverse;
  }
}

// Scales the xyz of tangents [first, last) to unit length and copies each rest tangent's w
// (rest null: keeps the w already stored), four vertices per step like Renormalise.
HWY_INLINE void RenormaliseTangents(float* HWY_RESTRICT tangents, const float* HWY_RESTRICT rest,
                                    std::size_t first, std::size_t last) {
  std::size_t v = first;
#if HWY_TARGET != HWY_SCALAR
  const D4 d4;
  for (; v + 4 <= last; v += 4) {
    V4 x, y, z, w;
    hn::LoadInterleaved4(d4, tangents + 4 * v, x, y, z, w);
    const V4 length = hn::Sqrt(hn::MulAdd(x, x, hn::MulAdd(y, y, hn::Mul(z, z))));
    const V4 inverse = hn::Div(hn::Set(d4, 1.0f), length);
    if (rest != nullptr) {
      V4 rx, ry, rz;
      hn::LoadInterleaved4(d4, rest + 4 * v, rx, ry, rz, w);
    }
    hn::StoreInterleaved4(hn::Mul(x, inverse), hn::Mul(y, inverse), hn::Mul(z, inverse), w, d4,
                          tangents + 4 * v);
  }
#endif
  for (; v < last; ++v) {
    float* t = tangents + 4 * v;
    const float inverse = 1.0f / std::sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
    t[0] *= inverse, t[1] *= inverse, t[2] *= inverse;
    if (rest != nullptr) t[3] = rest[4 * v + 3];
  }
}

template <int B, bool Normals, bool Tangents, typename Joint>
void SkinRangeT(const VertexStream& stream, const Joint* HWY_RESTRICT joints,
                const float* HWY_RESTRICT columns, float* HWY_RESTRICT out_p,
                float* HWY_RESTRICT out_n, float* HWY_RESTRICT out_t, std::size_t first,
                std::size_t last) {
  static_assert(Normals || !Tangents, "tangents come with normals");
  constexpr std::size_t kWeights = B - 1;
  constexpr std::size_t kChunk = 256;  // vertices whose normals are renormalised at once
  const Spread s;
  const float* HWY_RESTRICT positions = stream.positions;
  const float* HWY_RESTRICT normals = stream.normals;
  const float* HWY_RESTRICT tangents = stream.tangents;
  const float* HWY_RESTRICT weights = stream.weights;
  for (std::size_t chunk = first; chunk < last; chunk += kChunk) {
    const std::size_t chunk_end = std::min(last, chunk + kChunk);
    std::size_t v = chunk;
#if !SKINSERVE_SIMD_SIZELESS && HWY_TARGET != HWY_SCALAR
    if constexpr (kFourAtOnce) {
      // Four at a time while their 16-float loads and stores stay inside the range.
      const D d;
      const Quad<D> q;
      for (; v + 4 <= chunk_end && v + 6 <= last; v += 4) {
        const V p = hn::LoadU(d, positions + 3 * v);
        SkinFour<B, Normals, Tangents>(
            d, columns, s, q, p, Normals ? hn::LoadU(d, normals + 3 * v) : p,
            Tangents ? tangents + 4 * v : nullptr, joints + B * v, weights + kWeights * v,
            out_p + 3 * v, Normals ? out_n + 3 * v : nullptr, Tangents ? out_t + 4 * v : nullptr);
      }
    }
#endif
    // Every other vertex but the range's last stores straight into the outputs.
    const std::size_t direct_end = std::min(chunk_end, last - 1);
    for (; v < direct_end; ++v) {
      SkinVertex<B, Normals, Tangents>(
          columns, s, positions + 3 * v, Normals ? normals + 3 * v : nullptr,
          Tangents ? tangents + 4 * v : nullptr, joints + B * v, weights + kWeights * v,
          out_p + 3 * v, Normals ? out_n + 3 * v : nullptr, Tangents ? out_t + 4 * v : nullptr);
    }
    if (chunk_end == last) {  // the last vertex: local copies in and out
      const std::size_t l = last - 1;
      float in_p[4] = {positions[3 * l], positions[3 * l + 1], positions[3 * l + 2], 0};
      float in_n[4] = {};
      if constexpr (Normals) std::copy_n(normals + 3 * l, 3, in_n);
      float res_p[4], res_n[4];
      // (A tangent's 4-float store fills exactly its own vertex: no copy needed.)
      SkinVertex<B, Normals, Tangents>(
          columns, s, in_p, in_n, Tangents ? tangents + 4 * l : nullptr, joints + B * l,
          weights + kWeights * l, res_p, res_n, Tangents ? out_t + 4 * l : nullptr);
      std::copy_n(res_p, 3, out_p + 3 * l);
      if constexpr (Normals) std::copy_n(res_n, 3, out_n + 3 * l);
    }
    if constexpr (Normals) Renormalise(out_n, chunk, chunk_end);
    if constexpr (Tangents) RenormaliseTangents(out_t, tangents, chunk, chunk_end);
  }
}

void SkinRange(const VertexStream& stream, const float* columns, float* out_p, float* out_n,
               float* out_t, std::size_t first, std::size_t last) {
  if (first >= last) return;
  WithInfluences(stream.influences, [&](auto b) {
    constexpr int kB = decltype(b)::value;
    const auto run = [&](const auto* joints) {
      if (out_n == nullptr) {
        SkinRangeT<kB, false, false>(stream, joints, columns, out_p, out_n, out_t, first, last);
      } else if (out_t == nullptr) {
        SkinRangeT<kB, true, false>(stream, joints, columns, out_p, out_n, out_t, first, last);
      } else {
        SkinRangeT<kB, true, true>(stream, joints, columns, out_p, out_n, out_t, first, last);
      }
    };
    if (stream.joints8 != nullptr) {
      run(stream.joints8);
    } else {
      run(stream.joints16);
    }
  });
}

#if SKINSERVE_SIMD_SIZELESS || HWY_TARGET == HWY_SCALAR
// The quantized rest stream (QuantizedStream) on the SVE and HWY_SCALAR targets, a chunk at
// a time: its integers become floats in a 256-vertex scratch on the stack (about 13 KB at
// most, in L1), by plain loops the compiler vectorises, and the chunk takes the float loop
// above. Memory sees only the integers.
template <int B, bool Normals, bool Tangents, typename Joint, typename Weight>
void SkinQuantizedRangeT(const QuantizedStream& stream, const Joint* HWY_RESTRICT joints,
                         const Weight* HWY_RESTRICT weights, const float* HWY_RESTRICT columns,
                         float* HWY_RESTRICT out_p, float* HWY_RESTRICT out_n,
                         float* HWY_RESTRICT out_t, std::size_t first, std::size_t last) {
  constexpr std::size_t kChunk = 256;
  constexpr float kStep = 1.0f / static_cast<float>(hwy::LimitsMax<Weight>());
  // 4 floats past each chunk's positions and normals: SkinVertex reads 4 of each.
  alignas(64) float p[3 * kChunk + 4];
  alignas(64) float n[Normals ? 3 * kChunk + 4 : 1];
  alignas(64) float t[Tangents ? 4 * kChunk : 1];
  alignas(64) float w[(B - 1) * kChunk + 1];
  const float scale[3] = {stream.normal_scale[0], stream.normal_scale[1], stream.normal_scale[2]};
  for (std::size_t chunk = first; chunk < last; chunk += kChunk) {
    const std::size_t count = std::min(kChunk, last - chunk);
    const uint16_t* HWY_RESTRICT qp = stream.positions + 3 * chunk;
    for (std::size_t i = 0; i < 3 * count; ++i) p[i] = static_cast<float>(qp[i]);
    if constexpr (Normals) {
      const int16_t* HWY_RESTRICT qn = stream.normals + 3 * chunk;
      for (std::size_t v = 0; v < count; ++v) {
        for (int a = 0; a < 3; ++a) n[3 * v + a] = static_cast<float>(qn[3 * v + a]) * scale[a];
      }
    }
    if constexpr (Tangents) {  // xyz as the normals; w (+-32767) as +-1
      const int16_t* HWY_RESTRICT qt = stream.tangents + 4 * chunk;
      for (std::size_t v = 0; v < count; ++v) {
        for (int a = 0; a < 3; ++a) t[4 * v + a] = static_cast<float>(qt[4 * v + a]) * scale[a];
        t[4 * v + 3] = qt[4 * v + 3] < 0 ? -1.0f : 1.0f;
      }
    }
    const Weight* HWY_RESTRICT qw = weights + (B - 1) * chunk;
    for (std::size_t i = 0; i < (B - 1) * count; ++i) w[i] = static_cast<float>(qw[i]) * kStep;
    VertexStream decoded;
    decoded.influences = B;
    decoded.positions = p;
    decoded.normals = n;
    decoded.tangents = t;
    decoded.weights = w;
    SkinRangeT<B, Normals, Tangents>(decoded, joints + B * chunk, columns, out_p + 3 * chunk,
                                     Normals ? out_n + 3 * chunk : nullptr,
                                     Tangents ? out_t + 4 * chunk : nullptr, 0, count);
  }
}
#else
// xyz (and a fourth lane the transforms ignore) of the 4 integers at q, as floats: 8 bytes
// read, one widening and one conversion.
template <typename T>
HWY_INLINE V4 LoadConvert4(const T* HWY_RESTRICT q) {
  const hn::FixedTag<T, 4> dq;
  const hn::FixedTag<int32_t, 4> di;
  return hn::ConvertTo(D4(), hn::PromoteTo(di, hn::LoadU(dq, q)));
}

// TransformQuad with (x, y, z) in a register instead of memory: the same lane spread, from
// the register (kN = 4: three lane broadcasts; 8: two permutes; 16: one permute, as from
// memory).
template <bool Point, class DD>
HWY_INLINE V4 TransformRegisterQuad(DD d, const hn::Vec<DD>* HWY_RESTRICT m, const Spread& s,
                                    V4 xyz) {
  constexpr std::size_t kN = hn::MaxLanes(DD());
  if constexpr (kN == 4) {
    const auto x = hn::Broadcast<0>(xyz), y = hn::Broadcast<1>(xyz), z = hn::Broadcast<2>(xyz);
    const auto xc = Point ? hn::MulAdd(m[0], x, m[3]) : hn::Mul(m[0], x);
    return hn::MulAdd(m[2], z, hn::MulAdd(m[1], y, xc));
  } else {
    const hn::Half<DD> dh;
    const hn::Half<hn::Half<DD>> dq;
    const D4 d4;
    alignas(16) static constexpr float kKeep[4] = {1, 1, 1, 0};
    alignas(16) static constexpr float kUnit[4] = {0, 0, 0, 1};
    const V4 keep = hn::Load(d4, kKeep);
    const V4 xyzh = Point ? hn::MulAdd(xyz, keep, hn::Load(d4, kUnit)) : hn::Mul(xyz, keep);
    if constexpr (kN == 8) {
      const auto wide = hn::ZeroExtendVector(d, xyzh);
      const auto product = hn::MulAdd(m[1], hn::TableLookupLanes(wide, s.second),
                                      hn::Mul(m[0], hn::TableLookupLanes(wide, s.first)));
      return hn::Add(hn::LowerHalf(dh, product), hn::UpperHalf(dh, product));
    } else {
      const auto wide = hn::ZeroExtendVector(d, hn::ZeroExtendVector(dh, xyzh));
      const auto product = hn::Mul(m[0], hn::TableLookupLanes(wide, s.first));
      const auto sum8 = hn::Add(hn::LowerHalf(dh, product), hn::UpperHalf(dh, product));
      return hn::Add(hn::LowerHalf(dq, sum8), hn::UpperHalf(dq, sum8));
    }
  }
}

// SkinFour over a quantized chunk's vertices from `chunk` (its weights decoded in w) while
// their 16-integer loads and 16-float stores stay inside the range ending at `last`, the
// integers widened and converted in registers; returns the first vertex not skinned.
template <int B, bool Normals, typename Joint>
HWY_INLINE std::size_t SkinQuantizedFours(
    const QuantizedStream& stream, const Joint* HWY_RESTRICT joints, const float* HWY_RESTRICT w,
    const float* HWY_RESTRICT columns, const Spread& s, float* HWY_RESTRICT out_p,
    float* HWY_RESTRICT out_n, std::size_t chunk, std::size_t chunk_end, std::size_t last) {
  const D d;
  const Quad<D> q;
  const hn::Rebind<int32_t, D> di;
  alignas(64) float scale_pattern[16] = {};
  for (int i = 0; i < 12; ++i) scale_pattern[i] = stream.normal_scale[i % 3];
  const V scale12 = hn::Load(d, scale_pattern);
  std::size_t v = chunk;
  for (; v + 4 <= chunk_end && v + 6 <= last; v += 4) {
    const auto integers = hn::LoadU(hn::Rebind<uint16_t, D>(), stream.positions + 3 * v);
    const V p = hn::ConvertTo(d, hn::PromoteTo(di, integers));
    V n = p;
    if constexpr (Normals) {
      const auto normal = hn::LoadU(hn::Rebind<int16_t, D>(), stream.normals + 3 * v);
      n = hn::Mul(hn::ConvertTo(d, hn::PromoteTo(di, normal)), scale12);
    }
    SkinFour<B, Normals, false>(d, columns, s, q, p, n, nullptr, joints + B * v,
                                w + (B - 1) * (v - chunk), out_p + 3 * v,
                                Normals ? out_n + 3 * v : nullptr, nullptr);
  }
  return v;
}

// The quantized rest stream (QuantizedStream): each vertex's integer position (and normal)
// is converted in registers as it is skinned (LoadConvert4), while the weights, which the
// blend wants as broadcasts, are decoded a 256-vertex chunk at a time into an L1 scratch
// (a plain loop the compiler vectorises): from L1 a weight is a broadcast load, as in the
// float stream, where a conversion and a register broadcast per weight compete with the
// transform's lane permutes. Memory sees only the integers. The 8 bytes LoadConvert4 reads
// pass a vertex's 6: the range's last vertex goes through local copies.
template <int B, bool Normals, bool Tangents, typename Joint, typename Weight>
void SkinQuantizedRangeT(const QuantizedStream& stream, const Joint* HWY_RESTRICT joints,
                         const Weight* HWY_RESTRICT weights, const float* HWY_RESTRICT columns,
                         float* HWY_RESTRICT out_p, float* HWY_RESTRICT out_n,
                         float* HWY_RESTRICT out_t, std::size_t first, std::size_t last) {
  static_assert(Normals || !Tangents, "tangents come with normals");
  constexpr std::size_t kChunk = 256;  // also the vertices whose normals are renormalised at once
  constexpr float kStep = 1.0f / static_cast<float>(hwy::LimitsMax<Weight>());
  alignas(64) float w[(B - 1) * kChunk + 1];
  const Spread s;
  const D d;
  const D4 d4;
  alignas(16) const float scale_lanes[4] = {stream.normal_scale[0], stream.normal_scale[1],
                                            stream.normal_scale[2], 0.0f};
  const V4 scale = hn::Load(d4, scale_lanes);
  const uint16_t* HWY_RESTRICT qp = stream.positions;
  const int16_t* HWY_RESTRICT qn = stream.normals;
  const int16_t* HWY_RESTRICT qt = stream.tangents;
  for (std::size_t chunk = first; chunk < last; chunk += kChunk) {
    const std::size_t chunk_end = std::min(last, chunk + kChunk);
    const Weight* HWY_RESTRICT qw = weights + (B - 1) * chunk;
    for (std::size_t i = 0; i < (B - 1) * (chunk_end - chunk); ++i) {
      w[i] = static_cast<float>(qw[i]) * kStep;
    }
    const auto vertex = [&](std::size_t v, const uint16_t* p, const int16_t* n, float* op,
                            float* on) {
      const Blended m = Blend<B>(columns, joints + B * v, w + (B - 1) * (v - chunk));
      hn::StoreU(TransformRegisterQuad<true>(d, m.v, s, LoadConvert4(p)), d4, op);
      if constexpr (Normals) {
        const V4 normal = hn::Mul(LoadConvert4(n), scale);
        hn::StoreU(TransformRegisterQuad<false>(d, m.v, s, normal), d4, on);
      }
      if constexpr (Tangents) {  // its own 4 integers in, its own 4 floats out: no copies
        const int16_t* t = qt + 4 * v;
        float* ot = out_t + 4 * v;
        const V4 tangent = hn::Mul(LoadConvert4(t), scale);  // scale's fourth lane is 0
        hn::StoreU(TransformRegisterQuad<false>(d, m.v, s, tangent), d4, ot);
        ot[3] = t[3] < 0 ? -1.0f : 1.0f;
      }
    };
    std::size_t v = chunk;
    if constexpr (kFourAtOnce && !Tangents) {
      v = SkinQuantizedFours<B, Normals>(stream, joints, w, columns, s, out_p, out_n, chunk,
                                         chunk_end, last);
    }
    // Every other vertex but the range's last reads and stores in place.
    const std::size_t direct_end = std::min(chunk_end, last - 1);
    for (; v < direct_end; ++v) {
      vertex(v, qp + 3 * v, Normals ? qn + 3 * v : nullptr, out_p + 3 * v,
             Normals ? out_n + 3 * v : nullptr);
    }
    if (chunk_end == last) {  // the last vertex: local copies in and out
      const std::size_t l = last - 1;
      const uint16_t in_p[4] = {qp[3 * l], qp[3 * l + 1], qp[3 * l + 2], 0};
      int16_t in_n[4] = {};
      if constexpr (Normals) std::copy_n(qn + 3 * l, 3, in_n);
      float res_p[4], res_n[4];
      vertex(l, in_p, in_n, res_p, res_n);
      std::copy_n(res_p, 3, out_p + 3 * l);
      if constexpr (Normals) std::copy_n(res_n, 3, out_n + 3 * l);
    }
    if constexpr (Normals) Renormalise(out_n, chunk, chunk_end);
    if constexpr (Tangents) RenormaliseTangents(out_t, nullptr, chunk, chunk_end);
  }
}
#endif

void SkinQuantizedRange(const QuantizedStream& stream, const float* columns, float* out_p,
                        float* out_n, float* out_t, std::size_t first, std::size_t last) {
  if (first >= last) return;
  WithInfluences(stream.influences, [&](auto b) {
    constexpr int kB = decltype(b)::value;
    const auto run = [&](const auto* joints, const auto* weights) {
      using Joint = std::remove_cv_t<std::remove_pointer_t<decltype(joints)>>;
      using Weight = std::remove_cv_t<std::remove_pointer_t<decltype(weights)>>;
      if (out_n == nullptr) {
        SkinQuantizedRangeT<kB, false, false, Joint, Weight>(stream, joints, weights, columns,
                                                             out_p, out_n, out_t, first, last);
      } else if (out_t == nullptr) {
        SkinQuantizedRangeT<kB, true, false, Joint, Weight>(stream, joints, weights, columns, out_p,
                                                            out_n, out_t, first, last);
      } else {
        SkinQuantizedRangeT<kB, true, true, Joint, Weight>(stream, joints, weights, columns, out_p,
                                                           out_n, out_t, first, last);
      }
    };
    const auto with_weights = [&](const auto* joints) {
      if (stream.weights8 != nullptr) {
        run(joints, stream.weights8);
      } else {
        run(joints, stream.weights16);  // null for B = 1: never read
      }
    };
    if (stream.joints8 != nullptr) {
      with_weights(stream.joints8);
    } else {
      with_weights(stream.joints16);
    }
  });
}

// simd_dual_quaternion_kernel.cpp, compiled for the same targets.
void SkinDualQuaternionRange(const VertexStream& stream, const DualQuaternionFrame& palette,
                             float* out_p, float* out_n, float* out_t, std::size_t first,
                             std::size_t last);

Kernel GetKernel() {
  return Kernel{.skin_range = &SkinRange,
                .skin_dual_quaternion_range = &SkinDualQuaternionRange,
                .skin_quantized_range = &SkinQuantizedRange,
                .target = hwy::TargetName(HWY_TARGET),
                .lanes = static_cast<int>(kLanes)};
}

}  // namespace HWY_NAMESPACE
}  // namespace skinserve::simd
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
#include <mutex>

namespace skinserve::simd {

HWY_EXPORT(GetKernel);

namespace {

std::mutex& TargetMutex() {
  static std::mutex mutex;
  return mutex;
}

// Compiled here and run by this CPU, as a Highway target mask (lower bit: better).
int64_t RunnableMask() {
  hwy::DisableTargets(0);  // the CPU's own answer, no target held back
  return hwy::SupportedTargets() & HWY_TARGETS;
}

std::vector<std::string> Names(int64_t mask) {
  std::vector<std::string> names;
  for (int bit = 0; bit < 63; ++bit) {
    if (mask & (int64_t{1} << bit)) names.emplace_back(hwy::TargetName(int64_t{1} << bit));
  }
  return names;
}

// What Highway's dispatch may choose from outside SelectKernel's look-ups: 0 for the CPU's
// own answer, else the mask CapDispatch set.
int64_t dispatch_cap = 0;

// The runnable targets no better than `max_target` (empty: all), or 0 with `error` set.
int64_t AllowedUpTo(const std::string& max_target, std::string* error) {
  const int64_t runnable = RunnableMask();
  if (max_target.empty()) return runnable;
  for (int bit = 0; bit < 63; ++bit) {
    const int64_t target = int64_t{1} << bit;
    if ((runnable & target) && max_target == hwy::TargetName(target)) {
      return runnable & ~(target - 1);  // drop every better target
    }
  }
  std::string list;
  for (const std::string& name : Names(runnable)) list += (list.empty() ? "" : ", ") + name;
  *error = "SIMD target '" + max_target + "' is not one this build runs here (" + list + ")";
  return 0;
}

// Highway's dispatch chooses from `allowed` (0: every runnable target). DisableTargets
// replaces the previous call's mask rather than adding to it, so this also lifts a cap.
void Dispatch(int64_t allowed) {
  hwy::DisableTargets(allowed == 0 ? 0 : ~allowed);
  hwy::GetChosenTarget().Update(hwy::SupportedTargets());
}

}  // namespace

std::vector<std::string> RunnableTargets() {
  std::lock_guard<std::mutex> lock(TargetMutex());
  const std::vector<std::string> names = Names(RunnableMask());
  Dispatch(dispatch_cap);
  return names;
}

bool SelectKernel(const std::string& max_target, Kernel* kernel, std::string* error) {
  std::lock_guard<std::mutex> lock(TargetMutex());
  const int64_t allowed = AllowedUpTo(max_target, error);
  if (allowed != 0) {
    // Highway dispatches to the best target in SupportedTargets(): narrow it for this one
    // look-up, then give the process back what it had.
    Dispatch(allowed);
    *kernel = HWY_DYNAMIC_DISPATCH(GetKernel)();
  }
  Dispatch(dispatch_cap);
  return allowed != 0;
}

bool CapDispatch(const std::string& max_target, std::string* error) {
  std::lock_guard<std::mutex> lock(TargetMutex());
  const int64_t allowed = AllowedUpTo(max_target, error);
  if (allowed != 0) dispatch_cap = max_target.empty() ? 0 : allowed;
  Dispatch(dispatch_cap);
  return allowed != 0;
}

}  // namespace skinserve::simd
#endif  // HWY_ONCE
