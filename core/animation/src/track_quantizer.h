// A LINEAR or STEP translation, rotation or scale track quantized with `bits` a component:
// what the builder stores (the codes, ranges and smallest-three indices) and what the
// sampler will decode from it (`decoded`), made from the same codes so the two agree.
#pragma once

#include <cstdint>
#include <vector>

#include "skinserve/animation/raw_clip.h"

namespace skinserve::animation::detail {

struct QuantizedTrack {
  uint32_t bits = 16;
  uint32_t components = 0;       // a key's stored components: 3 (smallest-three or x y z)
  std::vector<float> ranges;     // per component: min, step
  std::vector<uint16_t> codes;   // per key, per component
  std::vector<uint8_t> largest;  // rotations: per key, the left-out component's index
  std::vector<float> decoded;    // per key, `width` floats as the sampler rebuilds them
};

// `t`: a LINEAR or STEP track of a joint (not weights, not CUBICSPLINE); bits kMinPackedBits..16.
QuantizedTrack QuantizeTrack(const RawTrack& t, uint32_t bits);

// Any track stored kRange16 (CUBICSPLINE's tangents too): its values as the sampler
// decodes them, in RawTrack's layout.
std::vector<float> DecodedRange16(const RawTrack& t);

}  // namespace skinserve::animation::detail
