// Quaternion helpers of the jobs (x y z w, float).
#pragma once

#include "isa_clones.h"

#include <cmath>

namespace skinserve::animation::detail {

SKINSERVE_ALWAYS_INLINE float Dot4(const float a[4], const float b[4]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
}

SKINSERVE_ALWAYS_INLINE void Normalize4(float q[4]) {
  const float inv = 1.0f / std::sqrt(Dot4(q, q));
  for (int c = 0; c < 4; ++c) q[c] *= inv;
}

// Shortest-path slerp, as glTF's LINEAR rotations: the sampled value must match the
// file's curve, and nlerp strays from it by up to ~theta^3/16 between keys. Without acos
// and sin: sin(u theta) / sin(theta) = u sum_i b_i (x - 1)^i with x = cos(theta) in [0, 1]
// (the shortest path), b_0 = 1, b_i = b_(i-1) (u^2 - i^2) / (i (2i + 1)), 8 terms and a
// corrected last one (D. Eberly, "A Fast and Accurate Algorithm for Computing SLERP",
// 2011): within 5e-7 rad of the true slerp for keys up to 2 rad of rotation apart, 2e-5 rad
// at the worst (180 degrees apart) (tests/animation/slerp_test.cpp).
// The series' coefficients, b_i = 1 + (u_i u^2 - v_i) (x - 1) b_(i+1) (Horner, i = 8 down to
// 1): u_i = m / (i (2i + 1)), v_i = m i / (2i + 1), m = 1 but for the corrected last term.
struct SlerpSeries {
  float u[9];
  float v[9];
};
inline constexpr SlerpSeries kSlerpSeries = [] {
  constexpr float kMu = 1.85298109240830f;  // the 8-term series' last-term correction
  SlerpSeries s{};
  for (int i = 1; i <= 8; ++i) {
    const float m = i == 8 ? kMu : 1.0f;
    s.u[i] = m / (static_cast<float>(i) * (2.0f * static_cast<float>(i) + 1.0f));
    s.v[i] = m * static_cast<float>(i) / (2.0f * static_cast<float>(i) + 1.0f);
  }
  return s;
}();

SKINSERVE_ALWAYS_INLINE void Slerp(const float a[4], const float b[4], float u, float out[4]) {
  float dot = Dot4(a, b);
  const float sign = dot < 0 ? -1.0f : 1.0f;
  const float xm1 = sign * dot - 1.0f;
  const float d = 1.0f - u, uu = u * u, dd = d * d;
  // Keys less than 0.4 rad of rotation apart (most, at 24 fps and up): (x - 1) < 0.02, and
  // 4 terms leave less than 1e-9 out.
  const int terms = xm1 > -0.02f ? 4 : 8;
  float fu = 1.0f, fd = 1.0f;  // Horner, from the last term down
  for (int i = terms; i >= 1; --i) {
    const float ui = kSlerpSeries.u[i], vi = kSlerpSeries.v[i];
    fu = 1.0f + fu * (ui * uu - vi) * xm1;
    fd = 1.0f + fd * (ui * dd - vi) * xm1;
  }
  const float wa = d * fd, wb = sign * u * fu;
  for (int c = 0; c < 4; ++c) out[c] = wa * a[c] + wb * b[c];
  Normalize4(out);
}

// a * b (apply b, then a).
SKINSERVE_ALWAYS_INLINE void Multiply(const float a[4], const float b[4], float out[4]) {
  out[0] = a[3] * b[0] + a[0] * b[3] + a[1] * b[2] - a[2] * b[1];
  out[1] = a[3] * b[1] - a[0] * b[2] + a[1] * b[3] + a[2] * b[0];
  out[2] = a[3] * b[2] + a[0] * b[1] - a[1] * b[0] + a[2] * b[3];
  out[3] = a[3] * b[3] - a[0] * b[0] - a[1] * b[1] - a[2] * b[2];
}

}  // namespace skinserve::animation::detail
