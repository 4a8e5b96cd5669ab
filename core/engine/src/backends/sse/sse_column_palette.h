// The frame's palette transposed for the SSE kernel: per joint four aligned __m128
// columns (m[0][c], m[1][c], m[2][c], 0), c = 0..3. A vertex then needs no horizontal
// sums: p' = x * col0 + y * col1 + z * col2 + col3, and the zero fourth lanes keep the
// normals' squared lengths clean.
#pragma once

#include <xmmintrin.h>

#include <cstddef>
#include <span>

#include "skinserve/model/aligned_buffer.h"

namespace skinserve::sse {

class ColumnPalette {
 public:
  static constexpr std::size_t kFloatsPerJoint = 16;

  // Builds into this thread's buffer (grown, never shrunk, so steady frames allocate
  // nothing). One frame at a time per thread: Skin() is synchronous, and OpenMP workers
  // only read the calling thread's buffer while it waits for them.
  explicit ColumnPalette(std::span<const float> palette) {
    thread_local AlignedBuffer<float> buffer;
    const std::size_t joints = palette.size() / 12;
    if (buffer.size() < joints * kFloatsPerJoint) {
      buffer = AlignedBuffer<float>(joints * kFloatsPerJoint);
    }
    columns_ = buffer.data();
    for (std::size_t j = 0; j < joints; ++j) {
      const float* rows = palette.data() + 12 * j;
      __m128 r0 = _mm_loadu_ps(rows), r1 = _mm_loadu_ps(rows + 4), r2 = _mm_loadu_ps(rows + 8);
      __m128 r3 = _mm_setzero_ps();
      _MM_TRANSPOSE4_PS(r0, r1, r2, r3);
      float* out = columns_ + kFloatsPerJoint * j;
      _mm_store_ps(out, r0);
      _mm_store_ps(out + 4, r1);
      _mm_store_ps(out + 8, r2);
      _mm_store_ps(out + 12, r3);
    }
  }
  ColumnPalette(const ColumnPalette&) = delete;
  ColumnPalette& operator=(const ColumnPalette&) = delete;

  // Joint j's four columns, 64-byte aligned.
  const float* joint(std::size_t j) const { return columns_ + kFloatsPerJoint * j; }

 private:
  float* columns_ = nullptr;
};

}  // namespace skinserve::sse
