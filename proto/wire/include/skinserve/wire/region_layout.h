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

// The bytes a frame of this shape takes, rounded up so that frames can follow each other.
inline uint64_t RegionFrameBytes(uint32_t vertices, uint32_t instances, VertexEncoding encoding,
                                 bool normals, bool tangents = false) {
  return RoundUpToRegionAlignment(
      LayoutInRegion(0, vertices, instances, encoding, normals, tangents).bytes());
}

}  // namespace skinserve::wire
