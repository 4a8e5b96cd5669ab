// Fuzzes the client's RawPart (a response part read from gRPC's bytes) against protobuf's
// own parser: the first byte picks how the rest is cut into gRPC slices; whenever protobuf
// parses the bytes as a SkinResponse, RawPart must too, with the same header, the same
// vertex field sizes, and the same floats decoded from the slices as from the parsed
// strings; bytes protobuf refuses, RawPart must refuse. Nothing may crash or overread.
#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "skinserve/encoding/vertex_encoding.h"
#include "skinserve/wire/raw_part.h"

namespace {

using skinserve::Bounds;
using skinserve::VertexEncoding;

bool SameFloats(const std::vector<float>& a, const std::vector<float>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const std::size_t slice = 1 + data[0] % 64;
  ++data;
  --size;
  std::vector<grpc::Slice> slices;
  for (std::size_t at = 0; at < size; at += slice) {
    slices.emplace_back(data + at, std::min(slice, size - at));
  }
  const grpc::ByteBuffer bytes(slices.data(), slices.size());
  skinserve::v1::SkinResponse parsed;
  const bool protobuf_ok = parsed.ParseFromArray(data, static_cast<int>(size));
  static skinserve::wire::RawPart raw;  // reused, as a stream reuses it
  const bool raw_ok = raw.Parse(bytes);
  if (raw_ok != protobuf_ok) std::abort();
  if (!raw_ok) return 0;
  if (raw.positions_size() != parsed.positions().size() ||
      raw.normals_size() != parsed.normals().size() ||
      raw.tangents_size() != parsed.tangents().size()) {
    std::abort();
  }
  skinserve::v1::SkinResponse header = parsed;
  header.clear_positions();
  header.clear_normals();
  header.clear_tangents();  // a vertex field too: RawPart keeps it out of the header
  if (header.SerializeAsString() != raw.header().SerializeAsString()) std::abort();
  // Decode every whole vertex of each field both ways, in each encoding.
  const Bounds box{{-1, -2, -3}, {4, 5, 6}};
  for (int e = 0; e < 3; ++e) {
    const auto encoding = static_cast<VertexEncoding>(e);
    const std::size_t triple = 3 * skinserve::EncodedBytesPerValue(encoding);
    for (bool normals : {false, true}) {
      const std::string& field = normals ? parsed.normals() : parsed.positions();
      const std::size_t vertices = field.size() / triple;
      std::vector<float> expected(3 * vertices), got(3 * vertices);
      const std::span<const std::byte> in(reinterpret_cast<const std::byte*>(field.data()),
                                          vertices * triple);
      const skinserve::Status want = normals
                                         ? skinserve::DecodeNormals(encoding, in, expected)
                                         : skinserve::DecodePositions(encoding, in, box, expected);
      const skinserve::Status s = raw.Decode(normals, 0, encoding, box, got);
      if (want.ok() != s.ok()) std::abort();
      if (want.ok() && !SameFloats(expected, got)) {
        // NaN bit patterns compare equal through memcmp; anything else must match.
        std::abort();
      }
    }
  }
  return 0;
}
