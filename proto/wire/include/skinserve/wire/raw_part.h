// RawPart: a StreamSkin response part read from the bytes gRPC received, without copying
// its vertex data: the header fields are parsed into a reused SkinResponse (positions and
// normals left empty) and the two vertex fields are decoded straight from gRPC's slices
// into the caller's floats. Parsing a part into a SkinResponse would first copy them into
// the message's strings. Any valid SkinResponse serialization is read, whatever its field
// order. One per stream, reused part after part: it allocates nothing once warm.
#pragma once

#include <google/protobuf/arena.h>
#include <grpcpp/grpcpp.h>

#include <cstddef>
#include <span>
#include <string>
#include <vector>

#include "skinserve/encoding/vertex_encoding.h"
#include "skinserve/model/status.h"
#include "skinserve/v1/skinning.pb.h"

namespace skinserve::wire {

class RawPart {
 public:
  RawPart();
  RawPart(const RawPart&) = delete;
  RawPart& operator=(const RawPart&) = delete;

  // Reads `bytes` (kept by the caller until the part is decoded); false if it is not a
  // SkinResponse.
  bool Parse(const grpc::ByteBuffer& bytes);

  // Every field but positions and normals; valid until the next Parse.
  const v1::SkinResponse& header() const {
    return header_ != nullptr ? *header_ : v1::SkinResponse::default_instance();
  }
  std::size_t positions_size() const { return positions_.size; }
  std::size_t normals_size() const { return normals_.size; }
  std::size_t tangents_size() const { return tangents_.size; }

  // Decodes bytes [offset, offset + EncodedBytesPerValue(encoding) * out.size()) of the
  // positions (or normals) field into `out`, as DecodePositions / DecodeNormals would;
  // the range must lie inside the field and `offset` start an x y z triple.
  Status Decode(bool normals, std::size_t offset, VertexEncoding encoding, const Bounds& bounds,
                std::span<float> out) const;
  // The same for the tangents field (x y z w: `offset` starts a vertex's 4 values).
  Status DecodeTangents(std::size_t offset, VertexEncoding encoding, std::span<float> out) const;

 private:
  struct Field {
    std::size_t offset = 0;  // of its data in the part's bytes
    std::size_t size = 0;
  };
  enum class Kind { kPositions, kNormals, kTangents };
  Status DecodeField(Kind kind, std::size_t offset, VertexEncoding encoding, const Bounds& bounds,
                     std::span<float> out) const;
  // The header lives in an arena over a block of this object, emptied at each Parse:
  // parsing into a reused message would free and allocate its sub-messages (timing,
  // bounds) every time.
  alignas(16) char arena_block_[8192];
  google::protobuf::Arena arena_;
  v1::SkinResponse* header_ = nullptr;  // in arena_, valid until the next Parse
  std::string field_bytes_;             // one length-delimited header field on its way
  std::string header_bytes_;            // the header fields, re-serialized for parsing
  std::vector<grpc::Slice> slices_;     // the part's bytes as gRPC holds them
  std::vector<std::size_t> starts_;     // each slice's offset in the part
  Field positions_, normals_, tangents_;
};

}  // namespace skinserve::wire
