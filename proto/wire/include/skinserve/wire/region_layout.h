// Where a frame's answer lies in a shared-memory region (SkinRequest.output): the rule of
// the wire contract, computed the same way by the server that writes and the client that
// reads. Positions of every instance back to back from the offset, then normals from the
// next multiple of kRegionAlignment.
#pragma once

#include <cstdint>

#include "skinserve/encoding/vertex_encoding.h"

namespace skinserve::wire {

// Offsets (a frame's and its normals') are multiples of this: a cache line, so two frames
// in one region never share one, and SIMD stores stay aligned.
inline constexpr uint64_t kRegionAlignment = 64;

struct RegionLayout {
  uint64_t positions_offset = 0;
  uint64_t normals_offset = 0;  // == positions_offset without normals
  uint64_t instance_bytes = 0;  // one instance's positions (or normals), encoded
  uint64_t end_offset = 0;      // one past the last byte of the frame

  uint64_t bytes() const { return end_offset - positions_offset; }
};

constexpr uint64_t RoundUpToRegionAlignment(uint64_t n) {
  return (n + kRegionAlignment - 1) / kRegionAlignment * kRegionAlignment;
}

inline RegionLayout LayoutInRegion(uint64_t offset, uint32_t vertices, uint32_t instances,
                                   VertexEncoding encoding, bool normals) {
  RegionLayout layout;
  layout.positions_offset = offset;
  layout.instance_bytes = uint64_t{vertices} * kValuesPerVertex * EncodedBytesPerValue(encoding);
  const uint64_t array_bytes = layout.instance_bytes * (instances == 0 ? 1 : instances);
  layout.normals_offset = normals ? offset + RoundUpToRegionAlignment(array_bytes) : offset;
  layout.end_offset = (normals ? layout.normals_offset : offset) + array_bytes;
  return layout;
}

// The bytes a frame of this shape takes, rounded up so that frames can follow each other.
inline uint64_t RegionFrameBytes(uint32_t vertices, uint32_t instances, VertexEncoding encoding,
                                 bool normals) {
  return RoundUpToRegionAlignment(
      LayoutInRegion(0, vertices, instances, encoding, normals).bytes());
}

}  // namespace skinserve::wire
