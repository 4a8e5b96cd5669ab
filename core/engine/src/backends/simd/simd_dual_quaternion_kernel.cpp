// The `simd` dual-quaternion kernel, written once with Google Highway and compiled for the
// same targets as the linear one (simd_kernel.cpp, whose GetKernel hands it out). The
// semantics are the scalar loop's (scalar_dual_quaternion_skinning.h): blend the B unit
// dual quaternions of the frame's DualQuaternionPalette, each one's sign chosen against
// the first influence, normalised by the real part's length, move the position; the normal
// and the tangent's xyz are rotated by the blended rotation (the tangent's w is kept).
//
// Two passes per chunk of 256 vertices, so each part runs where it is cheap:
//  1. the blend, one vertex at a time: a joint's record is one aligned 256-bit load on
//     AVX2 and AVX-512 (its rotation and dual part two 128-bit ones elsewhere), as the
//     linear loop loads whole matrix records; the frame's hemisphere table, when there is
//     one (DualQuaternionFrame::hemisphere), gives each record with its sign already chosen,
//     else the sign test is a 4-lane dot product;
//     the blended real and dual parts go to two small arrays (L1) instead of being
//     transposed in registers;
//  2. the transform, one vertex per lane at the full vector width, of the blend as it is
//     (its normalisation folded into one scale, TransformStep): the blends come back with
//     LoadInterleaved4, positions and normals with LoadInterleaved3 (tangents with
//     LoadInterleaved4), so this part is plain lane-wise arithmetic.
// (Gathering each component of each influence instead - 8 gathers an influence - measured
// 3.2x the linear loop at 400k x 4 on AVX-512; these two passes, 1.5x; with the hemisphere
// table and the folded normalisation, 1.32x on one VM thread, from 1.73x before them
// (docs/results/2026-11-27-dq-speed-vm).) No vector lives in a struct
// or an array, so SVE's sizeless vectors work as well. The chunk's last partial vector runs on
// padded local copies: nothing outside the range is written.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "backends/simd/simd_dual_quaternion_kernel.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include "backends/simd/simd_kernel_targets.h"
// Order matters: foreach_target.h first, then highway.h.
#include <hwy/highway.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <type_traits>

#include "backends/common/dual_quaternion_palette.h"
#include "backends/common/influence_dispatch.h"
#include "backends/simd/simd_stream.h"

HWY_BEFORE_NAMESPACE();
namespace skinserve::simd {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

namespace dq {

using D = hn::ScalableTag<float>;
using V = hn::Vec<D>;
// Lanes at most (SVE's upper bound where the length is chosen at run time).
constexpr std::size_t kMaxLanes = hn::MaxLanes(D());
constexpr std::size_t kStride = DualQuaternionPalette::kFloatsPerJoint;
constexpr std::size_t kChunk = 256;  // vertices blended before they are transformed

// Pass 1 for one vertex: the sum of w_i q_i, each q_i's sign chosen against the first
// influence's rotation, into real[0..3] and dual[0..3] (x, y, z, w). The weights are the
// stream's B - 1; the last is 1 - their sum (the mesh's weights sum to 1).
//
// With the frame's hemisphere table (DualQuaternionFrame::hemisphere) each influence's
// record is loaded with its sign already chosen, and the blend takes the linear loop's
// form (simd_kernel.cpp's Blend): q_last + sum over i < B - 1 of w_i (q_i - q_last), the
// weights broadcast straight from memory. Per influence that is a table look-up, a load, a
// subtraction and a multiply-add: no scalar arithmetic and no register broadcast.
// Without it (16-bit joints, or fewer vertices than the table's J x J entries) a dot
// product per influence decides the sign.
// The records of a vertex's B influences, each in the first one's hemisphere.
template <int B, typename Joint>
HWY_INLINE void HemisphereRecords(const float* HWY_RESTRICT quaternions,
                                  const uint16_t* HWY_RESTRICT hemisphere, uint32_t joint_count,
                                  const Joint* HWY_RESTRICT joints, const float** records) {
  const uint16_t* HWY_RESTRICT row = hemisphere + std::size_t{joint_count} * joints[0];
  records[0] = quaternions + kStride * joints[0];  // its own hemisphere
  for (int i = 1; i < B; ++i) records[i] = quaternions + row[joints[i]];
}

#if HWY_TARGET == HWY_SCALAR
template <int B, bool Table, typename Joint>
HWY_INLINE void BlendVertex(const float* HWY_RESTRICT quaternions,
                            const uint16_t* HWY_RESTRICT hemisphere, uint32_t joint_count,
                            const Joint* HWY_RESTRICT joints, const float* HWY_RESTRICT weights,
                            float* HWY_RESTRICT real, float* HWY_RESTRICT dual) {
  float b[8];
  if constexpr (Table) {
    const float* q[B];
    HemisphereRecords<B>(quaternions, hemisphere, joint_count, joints, q);
    for (std::size_t e = 0; e < 8; ++e) {
      float sum = q[B - 1][e];
      for (int i = 0; i < B - 1; ++i) sum += weights[i] * (q[i][e] - q[B - 1][e]);
      b[e] = sum;
    }
  } else {
    const float* q0 = quaternions + kStride * joints[0];
    float last_weight = 1.0f;
    const float w0 = B > 1 ? weights[0] : 1.0f;
    last_weight -= w0;
    for (std::size_t e = 0; e < 8; ++e) b[e] = w0 * q0[e];
    for (int i = 1; i < B; ++i) {
      const float* q = quaternions + kStride * joints[i];
      float w = last_weight;
      if (i + 1 < B) w = weights[i], last_weight -= w;
      const float dot = q0[0] * q[0] + q0[1] * q[1] + q0[2] * q[2] + q0[3] * q[3];
      if (dot < 0) w = -w;
      for (std::size_t e = 0; e < 8; ++e) b[e] += w * q[e];
    }
  }
  std::copy_n(b, 4, real);
  std::copy_n(b + 4, 4, dual);
}
#elif HWY_ARCH_X86 && HWY_TARGET <= HWY_AVX2
// AVX2 and AVX-512: a joint's whole record is one 256-bit vector, so each influence is one
// load and one multiply-add.
template <int B, bool Table, typename Joint>
HWY_INLINE void BlendVertex(const float* HWY_RESTRICT quaternions,
                            const uint16_t* HWY_RESTRICT hemisphere, uint32_t joint_count,
                            const Joint* HWY_RESTRICT joints, const float* HWY_RESTRICT weights,
                            float* HWY_RESTRICT real, float* HWY_RESTRICT dual) {
  const hn::FixedTag<float, 8> d8;
  const hn::FixedTag<float, 4> d4;
  hn::Vec<decltype(d8)> b;
  if constexpr (Table) {
    const float* q[B];
    HemisphereRecords<B>(quaternions, hemisphere, joint_count, joints, q);
    const auto base = hn::Load(d8, q[B - 1]);  // 32-byte aligned
    b = base;
    for (int i = 0; i < B - 1; ++i) {
      b = hn::MulAdd(hn::Set(d8, weights[i]), hn::Sub(hn::Load(d8, q[i]), base), b);
    }
  } else {
    const auto q0 = hn::Load(d8, quaternions + kStride * joints[0]);
    const auto r0 = hn::LowerHalf(d4, q0);
    float last_weight = 1.0f;
    const float w0 = B > 1 ? weights[0] : 1.0f;
    last_weight -= w0;
    b = hn::Mul(hn::Set(d8, w0), q0);
    for (int i = 1; i < B; ++i) {
      const auto q = hn::Load(d8, quaternions + kStride * joints[i]);
      float w = last_weight;
      if (i + 1 < B) w = weights[i], last_weight -= w;
      // q and -q are the same rotation: take the one in the first influence's hemisphere.
      const float dot = hn::GetLane(hn::SumOfLanes(d4, hn::Mul(r0, hn::LowerHalf(d4, q))));
      w = dot < 0 ? -w : w;
      b = hn::MulAdd(hn::Set(d8, w), q, b);
    }
  }
  hn::Store(hn::LowerHalf(d4, b), d4, real);
  hn::Store(hn::UpperHalf(d4, b), d4, dual);
}
#else
// 128-bit targets (SSE4, NEON, SVE at any length): the rotation and the dual part are one
// 4-lane vector each.
template <int B, bool Table, typename Joint>
HWY_INLINE void BlendVertex(const float* HWY_RESTRICT quaternions,
                            const uint16_t* HWY_RESTRICT hemisphere, uint32_t joint_count,
                            const Joint* HWY_RESTRICT joints, const float* HWY_RESTRICT weights,
                            float* HWY_RESTRICT real, float* HWY_RESTRICT dual) {
  const hn::FixedTag<float, 4> d4;
  hn::Vec<decltype(d4)> br, bd;
  if constexpr (Table) {
    const float* q[B];
    HemisphereRecords<B>(quaternions, hemisphere, joint_count, joints, q);
    const auto base_r = hn::Load(d4, q[B - 1]);  // the palette's records are 32-byte aligned
    const auto base_d = hn::Load(d4, q[B - 1] + 4);
    br = base_r, bd = base_d;
    for (int i = 0; i < B - 1; ++i) {
      const auto w = hn::Set(d4, weights[i]);
      br = hn::MulAdd(w, hn::Sub(hn::Load(d4, q[i]), base_r), br);
      bd = hn::MulAdd(w, hn::Sub(hn::Load(d4, q[i] + 4), base_d), bd);
    }
  } else {
    const float* q0 = quaternions + kStride * joints[0];
    const auto r0 = hn::Load(d4, q0);
    float last_weight = 1.0f;
    const float w0 = B > 1 ? weights[0] : 1.0f;
    last_weight -= w0;
    br = hn::Mul(hn::Set(d4, w0), r0);
    bd = hn::Mul(hn::Set(d4, w0), hn::Load(d4, q0 + 4));
    for (int i = 1; i < B; ++i) {
      const float* q = quaternions + kStride * joints[i];
      float w = last_weight;
      if (i + 1 < B) w = weights[i], last_weight -= w;
      const auto r = hn::Load(d4, q);
      // q and -q are the same rotation: take the one in the first influence's hemisphere.
      auto signed_w = hn::Set(d4, w);
      const auto dot = hn::SumOfLanes(d4, hn::Mul(r0, r));
      signed_w = hn::IfThenElse(hn::Lt(dot, hn::Zero(d4)), hn::Neg(signed_w), signed_w);
      br = hn::MulAdd(signed_w, r, br);
      bd = hn::MulAdd(signed_w, hn::Load(d4, q + 4), bd);
    }
  }
  hn::Store(br, d4, real);
  hn::Store(bd, d4, dual);
}
#endif

// 2 / n2. On x86 the CPU's reciprocal (12 or 14 bits) and one Newton-Raphson step (~23
// bits; the 1e-5 tolerance needs ~17) instead of a division, which holds the divider.
// Elsewhere the estimate has 8 bits (NEON, SVE) or is emulated: the exact form.
HWY_INLINE V TwiceInverse(V n2) {
  const D d;
#if HWY_ARCH_X86 && HWY_TARGET <= HWY_SSE4
  const V r = hn::ApproximateReciprocal(n2);
  // 2 r (2 - n2 r)
  return hn::Mul(hn::Add(r, r), hn::NegMulAdd(n2, r, hn::Set(d, 2.0f)));
#else
  return hn::Div(hn::Set(d, 2.0f), n2);
#endif
}

// 1 / sqrt(n2), the same way: the CPU's reciprocal square root and one Newton-Raphson step
// on x86 (a square root and a division take the divider ~22 cycles per 16 lanes).
HWY_INLINE V InverseLength(V n2) {
#if HWY_ARCH_X86 && HWY_TARGET <= HWY_SSE4
  const D d;
  const V r = hn::ApproximateReciprocalSqrt(n2);
  // r (1.5 - 0.5 n2 r^2)
  const V half_n2 = hn::Mul(hn::Set(d, 0.5f), n2);
  return hn::Mul(r, hn::NegMulAdd(half_n2, hn::Mul(r, r), hn::Set(d, 1.5f)));
#else
  return hn::Div(hn::Set(D(), 1.0f), hn::Sqrt(n2));
#endif
}

// (x, y, z) <- (x, y, z) + k b x (b x p + bw p), lane-wise: with k = 2 / |b|^2 the rotation
// by b / |b|, so the blend itself is never normalised (nor its dual part: see
// TransformStep).
HWY_INLINE void Rotate(V bx, V by, V bz, V bw, V k, V& x, V& y, V& z) {
  const V cx = hn::MulAdd(bw, x, hn::MulSub(by, z, hn::Mul(bz, y)));
  const V cy = hn::MulAdd(bw, y, hn::MulSub(bz, x, hn::Mul(bx, z)));
  const V cz = hn::MulAdd(bw, z, hn::MulSub(bx, y, hn::Mul(by, x)));
  x = hn::MulAdd(k, hn::MulSub(by, cz, hn::Mul(bz, cy)), x);
  y = hn::MulAdd(k, hn::MulSub(bz, cx, hn::Mul(bx, cz)), y);
  z = hn::MulAdd(k, hn::MulSub(bx, cy, hn::Mul(by, cx)), z);
}

// Pass 2 for Lanes(D) vertices: their blends (4 floats each in `real` and `dual`)
// applied to 3 floats per vertex of positions (and normals; 4 of tangents). With the blend
// (b, e) unnormalised and k = 2 / |b|^2, the unit dual quaternion (b, e) / |b| moves p to
//   p + k (b x (b x p + bw p) + bw e - ew b + b x e),
// rotation and translation (2 (rw s - sw r + r x s) for the unit (r, s)) under one scale:
// one reciprocal per vertex and no multiplications to normalise the eight components.
template <bool Normals, bool Tangents>
HWY_INLINE void TransformStep(const float* HWY_RESTRICT real, const float* HWY_RESTRICT dual,
                              const float* HWY_RESTRICT positions,
                              const float* HWY_RESTRICT normals, const float* HWY_RESTRICT tangents,
                              float* HWY_RESTRICT out_p, float* HWY_RESTRICT out_n,
                              float* HWY_RESTRICT out_t) {
  const D d;
  V bx, by, bz, bw, ex, ey, ez, ew;
  hn::LoadInterleaved4(d, real, bx, by, bz, bw);
  hn::LoadInterleaved4(d, dual, ex, ey, ez, ew);
  const V k =
      TwiceInverse(hn::MulAdd(bx, bx, hn::MulAdd(by, by, hn::MulAdd(bz, bz, hn::Mul(bw, bw)))));
  // bw e - ew b + b x e, the translation over k.
  const V ux = hn::MulAdd(bw, ex, hn::NegMulAdd(ew, bx, hn::MulSub(by, ez, hn::Mul(bz, ey))));
  const V uy = hn::MulAdd(bw, ey, hn::NegMulAdd(ew, by, hn::MulSub(bz, ex, hn::Mul(bx, ez))));
  const V uz = hn::MulAdd(bw, ez, hn::NegMulAdd(ew, bz, hn::MulSub(bx, ey, hn::Mul(by, ex))));
  V x, y, z;
  hn::LoadInterleaved3(d, positions, x, y, z);
  {
    const V cx = hn::MulAdd(bw, x, hn::MulSub(by, z, hn::Mul(bz, y)));
    const V cy = hn::MulAdd(bw, y, hn::MulSub(bz, x, hn::Mul(bx, z)));
    const V cz = hn::MulAdd(bw, z, hn::MulSub(bx, y, hn::Mul(by, x)));
    x = hn::MulAdd(k, hn::Add(hn::MulSub(by, cz, hn::Mul(bz, cy)), ux), x);
    y = hn::MulAdd(k, hn::Add(hn::MulSub(bz, cx, hn::Mul(bx, cz)), uy), y);
    z = hn::MulAdd(k, hn::Add(hn::MulSub(bx, cy, hn::Mul(by, cx)), uz), z);
  }
  hn::StoreInterleaved3(x, y, z, d, out_p);
  // Normals and tangents come out unit, as linear blending's: the rotation keeps a length,
  // and a morphed normal's is not 1.
  const auto normalize = [](V& vx, V& vy, V& vz) {
    const V inv = InverseLength(hn::MulAdd(vx, vx, hn::MulAdd(vy, vy, hn::Mul(vz, vz))));
    vx = hn::Mul(vx, inv), vy = hn::Mul(vy, inv), vz = hn::Mul(vz, inv);
  };
  if constexpr (Normals) {
    hn::LoadInterleaved3(d, normals, x, y, z);
    Rotate(bx, by, bz, bw, k, x, y, z);
    normalize(x, y, z);
    hn::StoreInterleaved3(x, y, z, d, out_n);
  }
  if constexpr (Tangents) {
    V w;
    hn::LoadInterleaved4(d, tangents, x, y, z, w);
    Rotate(bx, by, bz, bw, k, x, y, z);
    normalize(x, y, z);
    hn::StoreInterleaved4(x, y, z, w, d, out_t);
  }
}

template <int B, bool Normals, bool Tangents, bool Table, typename Joint>
void SkinRangeT(const VertexStream& stream, const Joint* HWY_RESTRICT joints,
                const DualQuaternionFrame& palette, float* HWY_RESTRICT out_p,
                float* HWY_RESTRICT out_n, float* HWY_RESTRICT out_t, std::size_t first,
                std::size_t last) {
  static_assert(Normals || !Tangents, "tangents come with normals");
  const float* HWY_RESTRICT quaternions = palette.quaternions;
  constexpr std::size_t kWeights = B - 1;
  const std::size_t lanes = hn::Lanes(D());
  const float* HWY_RESTRICT positions = stream.positions;
  const float* HWY_RESTRICT normals = stream.normals;
  const float* HWY_RESTRICT tangents = stream.tangents;
  const float* HWY_RESTRICT weights = stream.weights;
  // The chunk's blends, with room for a padded last vector.
  HWY_ALIGN float real[4 * (kChunk + kMaxLanes)], dual[4 * (kChunk + kMaxLanes)];
  for (std::size_t chunk = first; chunk < last; chunk += kChunk) {
    const std::size_t count = std::min(kChunk, last - chunk);
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t v = chunk + k;
      BlendVertex<B, Table>(quaternions, palette.hemisphere, palette.joint_count, joints + B * v,
                            weights + kWeights * v, real + 4 * k, dual + 4 * k);
    }
    std::size_t k = 0;
    for (; k + lanes <= count; k += lanes) {
      const std::size_t v = chunk + k;
      TransformStep<Normals, Tangents>(
          real + 4 * k, dual + 4 * k, positions + 3 * v, Normals ? normals + 3 * v : nullptr,
          Tangents ? tangents + 4 * v : nullptr, out_p + 3 * v, Normals ? out_n + 3 * v : nullptr,
          Tangents ? out_t + 4 * v : nullptr);
    }
    if (k == count) continue;
    // The last partial vector: copies of the chunk's last vertex fill the lanes past it.
    HWY_ALIGN float in_p[3 * kMaxLanes], in_n[3 * kMaxLanes], res_p[3 * kMaxLanes],
        res_n[3 * kMaxLanes], in_t[4 * kMaxLanes], res_t[4 * kMaxLanes];
    for (std::size_t lane = 0; lane < lanes; ++lane) {
      const std::size_t from = std::min(k + lane, count - 1);
      if (k + lane > from) {
        std::copy_n(real + 4 * from, 4, real + 4 * (k + lane));
        std::copy_n(dual + 4 * from, 4, dual + 4 * (k + lane));
      }
      std::copy_n(positions + 3 * (chunk + from), 3, in_p + 3 * lane);
      if constexpr (Normals) std::copy_n(normals + 3 * (chunk + from), 3, in_n + 3 * lane);
      if constexpr (Tangents) std::copy_n(tangents + 4 * (chunk + from), 4, in_t + 4 * lane);
    }
    TransformStep<Normals, Tangents>(real + 4 * k, dual + 4 * k, in_p, in_n, in_t, res_p, res_n,
                                     res_t);
    const std::size_t v = chunk + k;
    std::copy_n(res_p, 3 * (count - k), out_p + 3 * v);
    if constexpr (Normals) std::copy_n(res_n, 3 * (count - k), out_n + 3 * v);
    if constexpr (Tangents) std::copy_n(res_t, 4 * (count - k), out_t + 4 * v);
  }
}

}  // namespace dq

void SkinDualQuaternionRange(const VertexStream& stream, const DualQuaternionFrame& palette,
                             float* out_p, float* out_n, float* out_t, std::size_t first,
                             std::size_t last) {
  if (first >= last) return;
  WithInfluences(stream.influences, [&](auto b) {
    constexpr int kB = decltype(b)::value;
    const auto run = [&](auto normals, auto tangents, auto table, const auto* joints) {
      dq::SkinRangeT<kB, decltype(normals)::value, decltype(tangents)::value,
                     decltype(table)::value>(stream, joints, palette, out_p, out_n, out_t, first,
                                             last);
    };
    const auto with_joints = [&](auto normals, auto tangents) {
      if (stream.joints8 == nullptr) {
        run(normals, tangents, std::false_type{}, stream.joints16);
      } else if (palette.hemisphere != nullptr) {  // (8-bit joints only)
        run(normals, tangents, std::true_type{}, stream.joints8);
      } else {
        run(normals, tangents, std::false_type{}, stream.joints8);
      }
    };
    if (out_n == nullptr) {
      with_joints(std::false_type{}, std::false_type{});
    } else if (out_t == nullptr) {
      with_joints(std::true_type{}, std::false_type{});
    } else {
      with_joints(std::true_type{}, std::true_type{});
    }
  });
}

}  // namespace HWY_NAMESPACE
}  // namespace skinserve::simd
HWY_AFTER_NAMESPACE();
