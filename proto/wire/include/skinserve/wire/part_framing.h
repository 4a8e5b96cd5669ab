// How the server frames a StreamSkin answer part without copying its vertices into a
// message: the header (every SkinResponse field but positions and normals, serialized),
// the positions field's tag and length, the positions' bytes, then with normals the normals
// field's tag and length and their bytes, then with tangents the tangents field's. Concatenated,
// that is a valid SkinResponse serialization: any protobuf parser reads the part, and RawPart
// (raw_part.h, the clients' reader) reads it without copying. The server writes the framing into
// room it reserved beside its vertex buffer and hands gRPC slices of both.
#pragma once

#include <cstddef>
#include <span>

#include "skinserve/model/status.h"
#include "skinserve/v1/skinning.pb.h"

namespace skinserve::wire {

// A length-delimited field's tag and length take at most this many bytes: a tag of up to
// 2 bytes (field numbers < 2048; tangents are 17) and a length of up to 5 (fields < 32 GiB).
inline constexpr std::size_t kMaxFieldTagBytes = 7;

struct PartFraming {
  std::size_t header_bytes = 0;        // the header, then the positions field's tag and length
  std::size_t normals_tag_bytes = 0;   // the normals field's tag and length; 0 without normals
  std::size_t tangents_tag_bytes = 0;  // the tangents field's; 0 without tangents
};

// Writes `header` and the tags of a positions field (and, with `normals`, a normals field)
// of `payload_bytes` each into `room`, and with `tangent_bytes` > 0 a tangents field of that
// many. `header_size` is header.ByteSizeLong(), called just before (it caches the sizes the
// serialization uses). An error naming the sizes if the framing does not fit in `room`.
Result<PartFraming> WritePartFraming(const v1::SkinResponse& header, std::size_t header_size,
                                     std::size_t payload_bytes, bool normals,
                                     std::span<std::byte> room, std::size_t tangent_bytes = 0);

}  // namespace skinserve::wire
