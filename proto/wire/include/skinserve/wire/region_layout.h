// Where a frame's answer lies in a shared-memory region (SkinRequest.output): the rule of
// the wire contract, computed the same way by the server that writes and the client that
// reads. Positions of every instance back to back from the offset, then normals from the
// next multiple of kRegionAlignment, then tangents (4 values a vertex) from the next one.
#pragma once

#include <cstdint>

#include "skinserve/encoding/vertex_encoding.h"

namespace skinserve::wire {

// Offsets (a frame's and its normals') are multiples of this: a cache line, so two frames
// in one region never share one, and SIMD stores stay aligned.
inline constexpr uint64_t kRegionAlignment = 64;

struct RegionLayout {
  uint64_t positions_offset = 0;
  uint64_t normals_offset = 0;          // == positions_offset without normals
  uint64_t instance_bytes = 0;          // one instance's positions (or normals), encoded
  uint64_t tangents_offset = 0;         // == the normals' end without tangents
  uint64_t tangent_instance_bytes = 0;  // one instance's tangents, encoded; 0 without
  uint64_t end_offset = 0;              // one past the last byte of the frame

  uint64_t bytes() const { return end_offset - positions_offset; }
};

constexpr uint64_t RoundUpToRegionAlignment(uint64_t n) {
  return (n + kRegionAlignment - 1) / kRegionAlignment * kRegionAlignment;
}

// `tangents` needs `normals` (as SkinRequest.want_tangents does).
inline RegionLayout LayoutInRegion(uint64_t offset, uint32_t vertices, uint32_t instances,
                                   VertexEncoding encoding, bool normals, bool tangents = false) {
  RegionLayout layout;
  layout.positions_offset = offset;
  layout.instance_bytes = uint64_t{vertices} * kValuesPerVertex * EncodedBytesPerValue(encoding);
  const uint64_t count = instances == 0 ? 1 : instances;
  const uint64_t array_bytes = layout.instance_bytes * count;
  layout.normals_offset = normals ? offset + RoundUpToRegionAlignment(array_bytes) : offset;
  layout.end_offset = (normals ? layout.normals_offset : offset) + array_bytes;
  layout.tangents_offset = layout.end_offset;
  if (tangents) {
    layout.tangent_instance_bytes =
        uint64_t{vertices} * kValuesPerTangent * EncodedBytesPerValue(encoding);
    layout.tangents_offset = offset + RoundUpToRegionAlignment(layout.end_offset - offset);
    layout.end_offset = layout.tangents_offset + layout.tangent_instance_bytes * count;
  }
  return layout;
}

// Whether a frame of this shape at `offset` lies inside `region_bytes`. Every sum and
// product is checked for overflow, so that no offset or count a peer sends (an offset near
// 2^64, 2^32 instances of 2^32 vertices) can wrap around into a small end: a client must
// distrust the server's RegionWrite as much as the server distrusts a request's output.
inline bool LayoutFitsRegion(uint64_t offset, uint32_t vertices, uint32_t instances,
                             VertexEncoding encoding, bool normals, bool tangents,
                             uint64_t region_bytes) {
  const uint64_t count = instances == 0 ? 1 : instances;
  const uint64_t value_bytes = EncodedBytesPerValue(encoding);
  bool wrapped = false;
  const auto add = [&](uint64_t a, uint64_t b) {
    uint64_t sum = 0;
    wrapped |= __builtin_add_overflow(a, b, &sum);
    return sum;
  };
  const auto mul = [&](uint64_t a, uint64_t b) {
    uint64_t product = 0;
    wrapped |= __builtin_mul_overflow(a, b, &product);
    return product;
  };
  const auto round_up = [&](uint64_t n) {
    return add(n, kRegionAlignment - 1) / kRegionAlignment * kRegionAlignment;
  };
  const uint64_t array_bytes = mul(uint64_t{vertices} * kValuesPerVertex * value_bytes, count);
  uint64_t end = normals ? add(round_up(array_bytes), array_bytes) : array_bytes;
  if (tangents) {
    end = add(round_up(end), mul(uint64_t{vertices} * kValuesPerTangent * value_bytes, count));
  }
  return !wrapped && end <= region_bytes && offset <= region_bytes - end;
}

// The bytes a frame of this shape takes, rounded up so that frames can follow each other.
inline uint64_t RegionFrameBytes(uint32_t vertices, uint32_t instances, VertexEncoding encoding,
                                 bool normals, bool tangents = false) {
  return RoundUpToRegionAlignment(
      LayoutInRegion(0, vertices, instances, encoding, normals, tangents).bytes());
}

}  // namespace skinserve::wire
