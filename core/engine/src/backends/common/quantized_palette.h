// The box of a quantized rest stream folded into a frame's palette, once per frame, for
// every loop that skins the integers directly (`simd`'s columns, OpenCL's rows): each
// joint's 3x4 matrix M becomes M * diag(scale) with translation M * offset + t, so a
// position's three integers are skinned as they are (x = offset + scale * q per axis).
// In float64, rounded once.
#pragma once

#include "skinserve/model/quantized_rest.h"

namespace skinserve {

// `rows`: one joint's row-major 3x4 matrix; `out`: the folded one, row-major 3x4.
inline void FoldQuantizedBox(const float* rows, const QuantizedRest& rest, float* out) {
  for (int r = 0; r < 3; ++r) {
    const float* row = rows + 4 * r;
    double translation = row[3];
    for (int c = 0; c < 3; ++c) {
      out[4 * r + c] = static_cast<float>(double{row[c]} * rest.scale[c]);
      translation += double{row[c]} * rest.offset[c];
    }
    out[4 * r + 3] = static_cast<float>(translation);
  }
}

}  // namespace skinserve
