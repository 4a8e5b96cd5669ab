#include "skinserve/animation/local_to_model_job.h"

#include <fmt/format.h>

#include <algorithm>

#include "affine.h"
#include "float4.h"

namespace skinserve::animation {
namespace {

using detail::F4;

// Four joints' T * R * S as row-major 3x4s, computed side by side (SoA): each Transform is
// read as three overlapping 4-float loads (t xyz + qx, q xyzw, qw + s xyz), transposed to
// one lane a joint, and the matrices transposed back to rows.
SKINSERVE_ALWAYS_INLINE void ToAffine4(const Transform* t, Affine* out) {
  static_assert(sizeof(Transform) == 10 * sizeof(float));
  const float* f[4];
  for (int i = 0; i < 4; ++i) f[i] = t[i].translation;
  F4 tx = detail::Load4(f[0]), ty = detail::Load4(f[1]), tz = detail::Load4(f[2]),
     t3 = detail::Load4(f[3]);
  detail::Transpose(tx, ty, tz, t3);  // lanes: tx ty tz of each joint
  F4 x = detail::Load4(f[0] + 3), y = detail::Load4(f[1] + 3), z = detail::Load4(f[2] + 3),
     w = detail::Load4(f[3] + 3);
  detail::Transpose(x, y, z, w);
  F4 s0 = detail::Load4(f[0] + 6), sx = detail::Load4(f[1] + 6), sy = detail::Load4(f[2] + 6),
     sz = detail::Load4(f[3] + 6);
  detail::Transpose(s0, sx, sy, sz);  // s0: qw again
  const F4 one = detail::Splat(1), two = detail::Splat(2);
  const F4 xx = x * x, yy = y * y, zz = z * z, xy = x * y, xz = x * z, yz = y * z;
  const F4 wx = w * x, wy = w * y, wz = w * z;
  F4 r0[4] = {(one - two * (yy + zz)) * sx, two * (xy - wz) * sy, two * (xz + wy) * sz, tx};
  F4 r1[4] = {two * (xy + wz) * sx, (one - two * (xx + zz)) * sy, two * (yz - wx) * sz, ty};
  F4 r2[4] = {two * (xz - wy) * sx, two * (yz + wx) * sy, (one - two * (xx + yy)) * sz, tz};
  detail::Transpose(r0[0], r0[1], r0[2], r0[3]);  // now r0[i] is joint i's first row
  detail::Transpose(r1[0], r1[1], r1[2], r1[3]);
  detail::Transpose(r2[0], r2[1], r2[2], r2[3]);
  for (int i = 0; i < 4; ++i) {
    detail::Store4(r0[i], &out[i].m[0]);
    detail::Store4(r1[i], &out[i].m[4]);
    detail::Store4(r2[i], &out[i].m[8]);
  }
}

// Root down, 4 joints' local matrices at a time, compiled for each ISA (isa_clones.h).
SKINSERVE_ALWAYS_INLINE void LocalToModelBody(const int16_t* parents,
                                              std::span<const Transform> local,
                                              std::span<Affine> model) {
  const std::size_t n = local.size();
  Affine block[4];
  F4 p0 = detail::Splat(0), p1 = p0, p2 = p0;  // the last joint's model rows
  for (std::size_t first = 0; first < n; first += 4) {
    const std::size_t count = std::min<std::size_t>(4, n - first);
    if (count == 4) {
      ToAffine4(&local[first], block);
    } else {  // the last few joints, padded with identities
      Transform padded[4];
      std::copy_n(&local[first], count, padded);
      ToAffine4(padded, block);
    }
    // Parents come before children, so each joint's parent is final here (even when it
    // is in this block: the joints are composed in order). A parent that is the joint
    // just before (a chain: most joints) is still in registers.
    for (std::size_t i = 0; i < count; ++i) {
      const std::size_t j = first + i;
      const int parent = parents[j];
      const float* b = block[i].m;
      if (parent < 0) {
        p0 = detail::Load4(b), p1 = detail::Load4(b + 4), p2 = detail::Load4(b + 8);
      } else {
        if (static_cast<std::size_t>(parent) + 1 != j) {
          const float* a = model[static_cast<std::size_t>(parent)].m;
          p0 = detail::Load4(a), p1 = detail::Load4(a + 4), p2 = detail::Load4(a + 8);
        }
        const F4 b0 = detail::Load4(b), b1 = detail::Load4(b + 4), b2 = detail::Load4(b + 8);
        p0 = MultiplyAffineRow(p0, b0, b1, b2);
        p1 = MultiplyAffineRow(p1, b0, b1, b2);
        p2 = MultiplyAffineRow(p2, b0, b1, b2);
      }
      detail::Store4(p0, model[j].m);
      detail::Store4(p1, model[j].m + 4);
      detail::Store4(p2, model[j].m + 8);
    }
  }
}

void LocalToModelBaseline(const int16_t* parents, std::span<const Transform> local,
                          std::span<Affine> model) {
  LocalToModelBody(parents, local, model);
}

#if SKINSERVE_HAS_AVX2_FMA_CLONES
SKINSERVE_AVX2_FMA void LocalToModelAvx2Fma(const int16_t* parents,
                                            std::span<const Transform> local,
                                            std::span<Affine> model) {
  LocalToModelBody(parents, local, model);
}
#endif

}  // namespace

Status LocalToModelJob::Validate() const {
  if (skeleton == nullptr) return InvalidArgument("local-to-model: skeleton is missing");
  const std::size_t n = skeleton->joint_count();
  if (local.size() != n || model.size() != n) {
    return InvalidArgument(fmt::format(
        "local-to-model: local has {} transforms and model {} matrices; the skeleton has {} joints",
        local.size(), model.size(), n));
  }
  return Status::Ok();
}

Status LocalToModelJob::Run() const {
  if (Status s = Validate(); !s.ok()) return s;
#if SKINSERVE_HAS_AVX2_FMA_CLONES
  if (detail::RunAvx2Fma()) {
    LocalToModelAvx2Fma(skeleton->parents.data(), local, model);
    return Status::Ok();
  }
#endif
  LocalToModelBaseline(skeleton->parents.data(), local, model);
  return Status::Ok();
}

}  // namespace skinserve::animation
