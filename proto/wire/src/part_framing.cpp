#include "skinserve/wire/part_framing.h"

#include <fmt/format.h>

#include <algorithm>

namespace skinserve::wire {
namespace {

// A length-delimited field's tag and length (protobuf wire type 2) at `out`; returns the
// bytes written (at most kMaxFieldTagBytes).
std::size_t PutLengthDelimitedTag(int field, std::size_t length, std::byte* out) {
  std::size_t n = 0;
  // The tag is a varint too: fields from 16 on (tangents, 17) take two bytes.
  auto tag = static_cast<uint32_t>(field) << 3 | 2;
  for (; tag >= 0x80; tag >>= 7) out[n++] = static_cast<std::byte>((tag & 0x7f) | 0x80);
  out[n++] = static_cast<std::byte>(tag);
  do {
    const auto low = static_cast<uint8_t>(length & 0x7f);
    length >>= 7;
    out[n++] = static_cast<std::byte>(length ? (low | 0x80) : low);
  } while (length);
  return n;
}

}  // namespace

Result<PartFraming> WritePartFraming(const v1::SkinResponse& header, std::size_t header_size,
                                     std::size_t payload_bytes, bool normals,
                                     std::span<std::byte> room, std::size_t tangent_bytes) {
  const std::size_t tags = ((normals ? 2 : 1) + (tangent_bytes > 0 ? 1 : 0)) * kMaxFieldTagBytes;
  if (header_size + tags > room.size()) {
    return Internal(fmt::format("a response header of {} bytes exceeds the {} reserved",
                                header_size, room.size() - std::min(room.size(), tags)));
  }
  if (payload_bytes >> 35 != 0 || tangent_bytes >> 35 != 0) {
    return Internal(fmt::format("a part of {} bytes per vertex field is past the wire's framing",
                                payload_bytes));
  }
  std::byte* out = room.data();
  header.SerializeWithCachedSizesToArray(reinterpret_cast<uint8_t*>(out));
  PartFraming framing;
  framing.header_bytes =
      header_size + PutLengthDelimitedTag(v1::SkinResponse::kPositionsFieldNumber, payload_bytes,
                                          out + header_size);
  if (normals) {
    framing.normals_tag_bytes = PutLengthDelimitedTag(v1::SkinResponse::kNormalsFieldNumber,
                                                      payload_bytes, out + framing.header_bytes);
  }
  if (tangent_bytes > 0) {
    framing.tangents_tag_bytes =
        PutLengthDelimitedTag(v1::SkinResponse::kTangentsFieldNumber, tangent_bytes,
                              out + framing.header_bytes + framing.normals_tag_bytes);
  }
  return framing;
}

}  // namespace skinserve::wire
