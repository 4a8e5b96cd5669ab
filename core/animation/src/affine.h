// Row-major 3x4 affine products shared by the jobs.
#pragma once

#include "float4.h"
#include "skinserve/animation/transform.h"

namespace skinserve::animation {

// out = a * b (out may alias neither). Row r of out is a row-weighted sum of b's rows, four
// floats at a time, plus a's translation in the last lane, summed as two pairs: `a` is
// often the matrix just computed (local-to-model's parent), so the chain from it is short.
SKINSERVE_ALWAYS_INLINE void MultiplyAffine(const float* a, const float* b, float* out) {
  using namespace detail;
  const F4 b0 = Load4(&b[0]), b1 = Load4(&b[4]), b2 = Load4(&b[8]);
  for (int r = 0; r < 3; ++r) {
    const float* ar = &a[4 * r];
    const F4 row = (Broadcast(&ar[0]) * b0 + Set4(0, 0, 0, ar[3])) +
                   (Broadcast(&ar[1]) * b1 + Broadcast(&ar[2]) * b2);
    Store4(row, &out[4 * r]);
  }
}
SKINSERVE_ALWAYS_INLINE void MultiplyAffine(const Affine& a, const Affine& b, Affine& out) {
  MultiplyAffine(a.m, b.m, out.m);
}

// One row of a * b from a's row held in a register (the lanes broadcast by shuffles: no
// trip through memory for a matrix just computed), b's rows b0 b1 b2; summed as
// MultiplyAffine sums it.
SKINSERVE_ALWAYS_INLINE detail::F4 MultiplyAffineRow(detail::F4 a, detail::F4 b0, detail::F4 b1,
                                                     detail::F4 b2) {
  using namespace detail;
  return (SplatLane<0>(a) * b0 + KeepLane3(a)) + (SplatLane<1>(a) * b1 + SplatLane<2>(a) * b2);
}

}  // namespace skinserve::animation
