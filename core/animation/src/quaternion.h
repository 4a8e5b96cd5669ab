// Quaternion helpers of the jobs (x y z w, float).
#pragma once

#include <cmath>

namespace skinserve::animation::detail {

inline float Dot4(const float a[4], const float b[4]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
}

inline void Normalize4(float q[4]) {
  const float inv = 1.0f / std::sqrt(Dot4(q, q));
  for (int c = 0; c < 4; ++c) q[c] *= inv;
}

// Shortest-path slerp, as glTF's LINEAR rotations: the sampled value must match the
// file's curve, and nlerp strays from it by up to ~theta^3/16 between keys. Nearly equal
// keys take nlerp, where the two agree to float rounding.
inline void Slerp(const float a[4], const float b_in[4], float u, float out[4]) {
  float dot = Dot4(a, b_in);
  const float sign = dot < 0 ? -1.0f : 1.0f;
  dot *= sign;
  float wa = 1.0f - u, wb = u;
  if (dot < 0.9995f) {
    const float theta = std::acos(dot);
    const float inv_sin = 1.0f / std::sqrt(1.0f - dot * dot);
    wa = std::sin(wa * theta) * inv_sin;
    wb = std::sin(wb * theta) * inv_sin;
  }
  wb *= sign;
  for (int c = 0; c < 4; ++c) out[c] = wa * a[c] + wb * b_in[c];
  Normalize4(out);
}

// a * b (apply b, then a).
inline void Multiply(const float a[4], const float b[4], float out[4]) {
  out[0] = a[3] * b[0] + a[0] * b[3] + a[1] * b[2] - a[2] * b[1];
  out[1] = a[3] * b[1] - a[0] * b[2] + a[1] * b[3] + a[2] * b[0];
  out[2] = a[3] * b[2] + a[0] * b[1] - a[1] * b[0] + a[2] * b[3];
  out[3] = a[3] * b[3] - a[0] * b[0] - a[1] * b[1] - a[2] * b[2];
}

}  // namespace skinserve::animation::detail
