// Row-major 3x4 affine products shared by the jobs.
#pragma once

#include "skinserve/animation/transform.h"

namespace skinserve::animation {

// out = a * b (out must not alias a or b). Inline: it is most of local-to-model's time.
inline void MultiplyAffine(const Affine& a, const Affine& b, Affine& out) {
  for (int r = 0; r < 3; ++r) {
    const float* ar = &a.m[4 * r];
    for (int c = 0; c < 4; ++c) {
      out.m[4 * r + c] = ar[0] * b.m[c] + ar[1] * b.m[4 + c] + ar[2] * b.m[8 + c];
    }
    out.m[4 * r + 3] += ar[3];
  }
}

}  // namespace skinserve::animation
