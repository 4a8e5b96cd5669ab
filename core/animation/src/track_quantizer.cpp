#include "track_quantizer.h"

#include <algorithm>

#include "quantize.h"

namespace skinserve::animation::detail {
namespace {

// Each component against its range over the keys, `bits` a component.
void QuantizeColumns(const std::vector<float>& values, std::size_t keys, QuantizedTrack& q) {
  const uint32_t n = q.components;
  const float steps = QuantSteps(q.bits);
  for (uint32_t c = 0; c < n; ++c) {
    float lo = values[c], hi = values[c];
    for (std::size_t k = 0; k < keys; ++k) {
      lo = std::min(lo, values[k * n + c]);
      hi = std::max(hi, values[k * n + c]);
    }
    q.ranges.push_back(lo);
    q.ranges.push_back((hi - lo) / steps);
  }
  q.codes.resize(keys * n);
  for (std::size_t k = 0; k < keys; ++k) {
    for (uint32_t c = 0; c < n; ++c) {
      q.codes[k * n + c] =
          QuantizeRange(values[k * n + c], q.ranges[2 * c], q.ranges[2 * c + 1], steps);
    }
  }
}

float Decode(const QuantizedTrack& q, std::size_t k, uint32_t c) {
  return DequantizeRange(q.codes[k * q.components + c], q.ranges[2 * c], q.ranges[2 * c + 1]);
}

}  // namespace

QuantizedTrack QuantizeTrack(const RawTrack& t, uint32_t bits) {
  QuantizedTrack q;
  q.bits = bits;
  q.components = 3;
  const std::size_t keys = t.times.size();
  if (t.path != TrackPath::kRotation) {
    QuantizeColumns(t.values, keys, q);
    q.decoded.resize(keys * 3);
    for (std::size_t k = 0; k < keys; ++k) {
      for (uint32_t c = 0; c < 3; ++c) q.decoded[k * 3 + c] = Decode(q, k, c);
    }
    return q;
  }
  std::vector<float> slots(3 * keys);
  q.largest.resize(keys);
  for (std::size_t k = 0; k < keys; ++k) {
    q.largest[k] = static_cast<uint8_t>(SmallestThree(&t.values[4 * k], &slots[3 * k]));
  }
  QuantizeColumns(slots, keys, q);
  q.decoded.resize(keys * 4);
  for (std::size_t k = 0; k < keys; ++k) {
    const float small[3] = {Decode(q, k, 0), Decode(q, k, 1), Decode(q, k, 2)};
    FromSmallestThree(small, q.largest[k], &q.decoded[4 * k]);
  }
  return q;
}

std::vector<float> DecodedRange16(const RawTrack& t) {
  QuantizedTrack q;
  q.components =
      static_cast<uint32_t>(t.width * (t.interpolation == Interpolation::kCubicSpline ? 3 : 1));
  const std::size_t keys = t.times.size();
  QuantizeColumns(t.values, keys, q);
  std::vector<float> decoded(keys * q.components);
  for (std::size_t k = 0; k < keys; ++k) {
    for (uint32_t c = 0; c < q.components; ++c) decoded[k * q.components + c] = Decode(q, k, c);
  }
  return decoded;
}

}  // namespace skinserve::animation::detail
