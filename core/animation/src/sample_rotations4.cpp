#include "sample_rotations4.h"

#include "float4.h"
#include "quantize.h"
#include "quaternion.h"

namespace skinserve::animation::detail {
namespace {

struct Quat4 {  // four quaternions, one a lane
  F4 x, y, z, w;
};

// The largest slot rebuilt from the three stored ones and placed 4-wide by its index.
SKINSERVE_ALWAYS_INLINE Quat4 Rebuild(const float slot[3][4], const float largest[4]) {
  const F4 s0 = Load4(slot[0]), s1 = Load4(slot[1]), s2 = Load4(slot[2]);
  const F4 big = Sqrt(Max(Splat(0), Splat(1) - (s0 * s0 + s1 * s1 + s2 * s2)));
  const F4 l = Load4(largest);
  const F4 is0 = Equal(l, Splat(0)), is1 = Equal(l, Splat(1)), is2 = Equal(l, Splat(2)),
           is3 = Equal(l, Splat(3));
  // The largest at its index, the three others in order around it.
  return {Select(is0, big, s0), Select(is0, s0, Select(is1, big, s1)),
          Select(is2, big, Select(is3, s2, s1)), Select(is3, big, s2)};
}

SKINSERVE_ALWAYS_INLINE float LargestIndex(const CompactClip& clip, uint32_t at) {
  return static_cast<float>((clip.largest[at / 4] >> (2 * (at % 4))) & 3);
}

// Key k of a 16-bit group's four tracks: the three stored slots dequantized one lane at a
// time (each track has its own ranges and largest index), then rebuilt 4-wide.
SKINSERVE_ALWAYS_INLINE Quat4 DecodeKeys(const CompactClip& clip,
                                         const SamplingPlan::RotationGroup& g, uint32_t k) {
  alignas(16) float slot[3][4];
  alignas(16) float largest[4];
  for (int lane = 0; lane < 4; ++lane) {
    const uint16_t* q = &clip.words[g.bytes[lane] / 2 + 3 * k];
    for (int c = 0; c < 3; ++c) slot[c][lane] = g.min[lane][c] + g.step[lane][c] * q[c];
    largest[lane] = LargestIndex(clip, g.largest[lane] + k);
  }
  return Rebuild(slot, largest);
}

// The same for a packed group: each lane's slots cut out of one 8-byte read.
SKINSERVE_ALWAYS_INLINE Quat4 DecodePackedKeys(const CompactClip& clip,
                                               const SamplingPlan::RotationGroup& g, uint32_t k) {
  alignas(16) float slot[3][4];
  alignas(16) float largest[4];
  for (int lane = 0; lane < 4; ++lane) {
    uint32_t q[3];
    ReadKey3(clip.packed.data() + g.bytes[lane], k, g.bits[lane], q);
    for (int c = 0; c < 3; ++c)
      slot[c][lane] = DequantizeCode(q[c], g.min[lane][c], g.step[lane][c]);
    largest[lane] = LargestIndex(clip, g.largest[lane] + k);
  }
  return Rebuild(slot, largest);
}

SKINSERVE_ALWAYS_INLINE Quat4 Decode(const CompactClip& clip, const SamplingPlan::RotationGroup& g,
                                     uint32_t k) {
  return g.packed[0] != 0 ? DecodePackedKeys(clip, g, k) : DecodeKeys(clip, g, k);
}

// sin(u theta) / sin(theta) / u (and for 1 - u) by quaternion.h's series, `terms` terms
// (a constant, so the loop unrolls).
template <int terms>
SKINSERVE_ALWAYS_INLINE void SlerpFactors(F4 xm1, float uu, float dd, F4& fu, F4& fd) {
  fu = Splat(1);
  fd = Splat(1);
  for (int i = terms; i >= 1; --i) {
    const float ui = kSlerpSeries.u[i], vi = kSlerpSeries.v[i];
    fu = Splat(1) + fu * (Splat(ui * uu - vi) * xm1);
    fd = Splat(1) + fd * (Splat(ui * dd - vi) * xm1);
  }
}

// quaternion.h's Slerp (Eberly's series, 4 terms when every lane's keys are < 0.4 rad
// apart, else 8), one lane a track.
SKINSERVE_ALWAYS_INLINE Quat4 Slerp4(const Quat4& a, const Quat4& b, float u) {
  const F4 dot = a.x * b.x + a.y * b.y + a.z * b.z + a.w * b.w;
  const F4 sign = SignOf(dot);
  const F4 xm1 = sign * dot - Splat(1);
  const float d = 1.0f - u, uu = u * u, dd = d * d;
  F4 fu, fd;
  if (AllGreater(xm1, Splat(-0.02f))) {
    SlerpFactors<4>(xm1, uu, dd, fu, fd);
  } else {
    SlerpFactors<8>(xm1, uu, dd, fu, fd);
  }
  const F4 wa = Splat(d) * fd, wb = sign * Splat(u) * fu;
  Quat4 q{wa * a.x + wb * b.x, wa * a.y + wb * b.y, wa * a.z + wb * b.z, wa * a.w + wb * b.w};
  const F4 inv = InverseSqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
  return {q.x * inv, q.y * inv, q.z * inv, q.w * inv};
}

SKINSERVE_ALWAYS_INLINE Quat4 LoadQuat4(const float* p) {
  return {Load4(p), Load4(p + 4), Load4(p + 8), Load4(p + 12)};
}
SKINSERVE_ALWAYS_INLINE void StoreQuat4(const Quat4& q, float* p) {
  Store4(q.x, p);
  Store4(q.y, p + 4);
  Store4(q.z, p + 8);
  Store4(q.w, p + 12);
}

SKINSERVE_ALWAYS_INLINE void SampleRotations4Body(
    const CompactClip& clip, std::span<const SamplingPlan::RotationGroup> groups, uint32_t k,
    uint32_t next, float u, std::span<Transform> output, RotationKeys keys) {
  for (std::size_t i = 0; i < groups.size(); ++i) {
    const SamplingPlan::RotationGroup& g = groups[i];
    float* cache = keys.cache == nullptr ? nullptr : keys.cache + 32 * i;
    Quat4 a, b;
    if (keys.state == RotationKeys::kCached) {
      a = LoadQuat4(cache);
      b = LoadQuat4(cache + 16);
    } else {
      a = keys.state == RotationKeys::kShift ? LoadQuat4(cache + 16) : Decode(clip, g, k);
      b = next == k ? a : Decode(clip, g, next);
      if (cache != nullptr) {
        StoreQuat4(a, cache);
        StoreQuat4(b, cache + 16);
      }
    }
    Quat4 q = next == k ? a : Slerp4(a, b, u);
    Transpose(q.x, q.y, q.z, q.w);  // now one quaternion a vector
    // Every lane: a last group's padding lanes repeat its first track, so they write the
    // same rotation to the same joint again (no lane count to test).
    Store4(q.x, output[g.joint[0]].rotation);
    Store4(q.y, output[g.joint[1]].rotation);
    Store4(q.z, output[g.joint[2]].rotation);
    Store4(q.w, output[g.joint[3]].rotation);
  }
}

void SampleRotations4Baseline(const CompactClip& clip,
                              std::span<const SamplingPlan::RotationGroup> groups, uint32_t k,
                              uint32_t next, float u, std::span<Transform> output,
                              RotationKeys keys) {
  SampleRotations4Body(clip, groups, k, next, u, output, keys);
}

#if SKINSERVE_HAS_AVX2_FMA_CLONES
SKINSERVE_AVX2_FMA void SampleRotations4Avx2Fma(const CompactClip& clip,
                                                std::span<const SamplingPlan::RotationGroup> groups,
                                                uint32_t k, uint32_t next, float u,
                                                std::span<Transform> output, RotationKeys keys) {
  SampleRotations4Body(clip, groups, k, next, u, output, keys);
}
#endif

}  // namespace

void SampleRotations4(const CompactClip& clip, std::span<const SamplingPlan::RotationGroup> groups,
                      uint32_t k, uint32_t next, float u, std::span<Transform> output,
                      RotationKeys keys) {
#if SKINSERVE_HAS_AVX2_FMA_CLONES
  if (RunAvx2Fma()) return SampleRotations4Avx2Fma(clip, groups, k, next, u, output, keys);
#endif
  SampleRotations4Baseline(clip, groups, k, next, u, output, keys);
}

}  // namespace skinserve::animation::detail
