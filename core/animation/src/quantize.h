// The compact clip's encodings of one value, shared by the builder and the sampler so the
// two can never disagree: 16-bit range quantization and smallest-three quaternions.
#pragma once

#include "isa_clones.h"

#include <cmath>
#include <cstdint>
#include <cstring>

namespace skinserve::animation::detail {

inline constexpr float kQuantSteps = 65535.0f;
inline constexpr float kSqrtHalf = 0.70710678118654752f;

// The steps a range is cut into with `bits` a component: 2^bits - 1.
inline float QuantSteps(uint32_t bits) { return static_cast<float>((1u << bits) - 1u); }

inline uint16_t QuantizeRange(float v, float min, float step, float steps = kQuantSteps) {
  if (!(step > 0)) return 0;
  const float q = std::round((v - min) / step);
  return static_cast<uint16_t>(q < 0 ? 0 : (q > steps ? steps : q));
}
SKINSERVE_ALWAYS_INLINE float DequantizeRange(uint16_t q, float min, float step) {
  return min + step * q;
}
// A packed code (< 2^16): converted as a signed int, the one instruction u16 takes too.
SKINSERVE_ALWAYS_INLINE float DequantizeCode(uint32_t q, float min, float step) {
  return min + step * static_cast<float>(static_cast<int32_t>(q));
}

// The `bits`-bit value at bit `at` of `base` (little-endian bit order). Reads 8 bytes:
// CompactClip::packed ends in kPackedSlack zero bytes.
SKINSERVE_ALWAYS_INLINE uint32_t ReadBits(const uint8_t* base, uint64_t at, uint32_t bits) {
  uint64_t v;
  std::memcpy(&v, base + (at >> 3), sizeof v);
  return static_cast<uint32_t>(v >> (at & 7)) & ((1u << bits) - 1u);
}
// Key k's three `bits`-wide components (bits <= 16) of a packed track whose keys start at
// `base`: one 8-byte read (CompactClip::packed ends in kPackedSlack zero bytes).
SKINSERVE_ALWAYS_INLINE void ReadKey3(const uint8_t* base, uint32_t k, uint32_t bits,
                                      uint32_t out[3]) {
  const uint32_t at = 3 * k * bits;  // k < 65536, bits <= 16: no overflow
  uint64_t v;
  std::memcpy(&v, base + (at >> 3), sizeof v);
  v >>= at & 7;
  const uint64_t mask = (uint64_t{1} << bits) - 1u;
  out[0] = static_cast<uint32_t>(v & mask);
  out[1] = static_cast<uint32_t>((v >> bits) & mask);
  out[2] = static_cast<uint32_t>((v >> (2 * bits)) & mask);
}

inline void WriteBits(uint8_t* base, uint64_t at, uint32_t bits, uint32_t value) {
  for (uint32_t b = 0; b < bits; ++b, ++at) {
    if ((value >> b) & 1u) base[at >> 3] = static_cast<uint8_t>(base[at >> 3] | (1u << (at & 7)));
  }
}

// Smallest-three: q and -q are one rotation, so the largest component is made positive
// and left out; the other three (in order) lie in [-1/sqrt2, 1/sqrt2]. Returns its index.
inline int SmallestThree(const float q_in[4], float out[3]) {
  double q[4];
  double length = 0;
  for (int c = 0; c < 4; ++c) length += double{q_in[c]} * q_in[c];
  length = std::sqrt(length);
  int largest = 0;
  for (int c = 0; c < 4; ++c) {
    q[c] = q_in[c] / length;
    if (std::fabs(q[c]) > std::fabs(q[largest])) largest = c;
  }
  const double sign = q[largest] < 0 ? -1.0 : 1.0;
  for (int c = 0, k = 0; c < 4; ++c) {
    if (c != largest) out[k++] = static_cast<float>(sign * q[c]);
  }
  return largest;
}

// The rotation from its three smaller components and the largest one's index.
SKINSERVE_ALWAYS_INLINE void FromSmallestThree(const float small[3], int largest, float q[4]) {
  float sum = 0;
  for (int c = 0, k = 0; c < 4; ++c) {
    if (c == largest) continue;
    q[c] = small[k++];
    sum += q[c] * q[c];
  }
  q[largest] = std::sqrt(1.0f - sum > 0.0f ? 1.0f - sum : 0.0f);
}

}  // namespace skinserve::animation::detail
