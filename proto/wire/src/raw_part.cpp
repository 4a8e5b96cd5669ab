#include "skinserve/wire/raw_part.h"

#include <fmt/format.h>
#include <google/protobuf/io/coded_stream.h>
#include <google/protobuf/io/zero_copy_stream_impl_lite.h>
#include <google/protobuf/wire_format_lite.h>
#include <grpcpp/support/proto_buffer_reader.h>

#include <algorithm>
#include <cstring>

namespace skinserve::wire {
namespace {

using google::protobuf::internal::WireFormatLite;

google::protobuf::ArenaOptions OverBlock(char* block, std::size_t size) {
  google::protobuf::ArenaOptions options;
  options.initial_block = block;
  options.initial_block_size = size;
  return options;
}

using google::protobuf::io::CodedInputStream;
using google::protobuf::io::CodedOutputStream;

// protobuf's parser takes a tag or a length of at most 5 bytes (CodedInputStream reads up
// to 10 and drops the excess): refuse what it refuses, at every depth.
bool ReadTag(CodedInputStream& input, uint32_t* tag) {
  const int at = input.CurrentPosition();
  *tag = input.ReadTag();
  return input.CurrentPosition() - at <= 5;
}

// A length no longer than protobuf takes and no larger than the `total` bytes can hold.
bool ReadLength(CodedInputStream& input, std::size_t total, uint32_t* length) {
  const int at = input.CurrentPosition();
  return input.ReadVarint32(length) && input.CurrentPosition() - at <= 5 &&
         *length <= total - static_cast<std::size_t>(input.CurrentPosition());
}

// Deeper groups than protobuf's recursion limit (100) are refused by the header's parse
// below; this bound only keeps the copy's own recursion finite.
constexpr int kDeepestGroup = 128;

// Copies one kept (header) field from `input` to `out`. Groups are copied field by field
// with the same checks as the top level: WireFormatLite::SkipField would rewrite an
// overlong tag inside a group as a canonical one, which protobuf refuses.
bool CopyKeptField(CodedInputStream& input, uint32_t tag, std::size_t total, CodedOutputStream& out,
                   std::string& scratch, int depth = 0) {
  switch (WireFormatLite::GetTagWireType(tag)) {
    case WireFormatLite::WIRETYPE_LENGTH_DELIMITED: {
      uint32_t length = 0;
      if (!ReadLength(input, total, &length)) return false;
      scratch.resize(length);  // one string reused (SkipField would use a fresh one)
      if (!input.ReadRaw(scratch.data(), static_cast<int>(length))) return false;
      out.WriteTag(tag);
      out.WriteVarint32(length);
      out.WriteRaw(scratch.data(), static_cast<int>(length));
      return true;
    }
    case WireFormatLite::WIRETYPE_START_GROUP: {
      if (depth >= kDeepestGroup) return false;
      out.WriteTag(tag);
      while (true) {
        uint32_t inner = 0;
        if (!ReadTag(input, &inner) || inner == 0) return false;
        if (WireFormatLite::GetTagWireType(inner) == WireFormatLite::WIRETYPE_END_GROUP) {
          if (WireFormatLite::GetTagFieldNumber(inner) != WireFormatLite::GetTagFieldNumber(tag))
            return false;
          out.WriteTag(inner);
          return true;
        }
        if (!CopyKeptField(input, inner, total, out, scratch, depth + 1)) return false;
      }
    }
    case WireFormatLite::WIRETYPE_END_GROUP:
      return false;  // an end without its start
    default:
      return WireFormatLite::SkipField(&input, tag, &out);  // varints and fixed: no tags
  }
}

}  // namespace

RawPart::RawPart() : arena_(OverBlock(arena_block_, sizeof arena_block_)) {}

bool RawPart::Parse(const grpc::ByteBuffer& bytes) {
  positions_ = normals_ = tangents_ = {};
  header_bytes_.clear();
  // The reader only reads (gRPC's ProtoBufferReader takes a non-const buffer).
  grpc::ProtoBufferReader reader(const_cast<grpc::ByteBuffer*>(&bytes));
  if (!reader.status().ok()) return false;
  {
    CodedInputStream input(&reader);
    google::protobuf::io::StringOutputStream header_stream(&header_bytes_);
    CodedOutputStream header_out(&header_stream);
    while (true) {
      uint32_t tag = 0;
      if (!ReadTag(input, &tag)) return false;
      if (tag == 0) break;
      const int field = WireFormatLite::GetTagFieldNumber(tag);
      const bool vertex_field = field == v1::SkinResponse::kPositionsFieldNumber ||
                                field == v1::SkinResponse::kNormalsFieldNumber ||
                                field == v1::SkinResponse::kTangentsFieldNumber;
      if (!vertex_field ||
          WireFormatLite::GetTagWireType(tag) != WireFormatLite::WIRETYPE_LENGTH_DELIMITED) {
        // Kept, to be parsed below.
        if (!CopyKeptField(input, tag, bytes.Length(), header_out, field_bytes_)) return false;
        continue;
      }
      uint32_t length = 0;
      if (!ReadLength(input, bytes.Length(), &length)) return false;
      // A repeated field: the last one counts, as when parsing.
      Field& f = field == v1::SkinResponse::kPositionsFieldNumber ? positions_
                 : field == v1::SkinResponse::kNormalsFieldNumber ? normals_
                                                                  : tangents_;
      f = {static_cast<std::size_t>(input.CurrentPosition()), length};
      if (!input.Skip(static_cast<int>(length))) return false;
    }
    if (!input.ConsumedEntireMessage()) return false;
  }
  header_ = nullptr;
  arena_.Reset();  // keeps the block: no heap allocation
  header_ = google::protobuf::Arena::CreateMessage<v1::SkinResponse>(&arena_);
  if (!header_->ParseFromString(header_bytes_)) return false;
  if (!bytes.Dump(&slices_).ok()) return false;
  starts_.clear();
  std::size_t at = 0;
  for (const grpc::Slice& s : slices_) {
    starts_.push_back(at);
    at += s.size();
  }
  return true;
}

Status RawPart::Decode(bool normals, std::size_t offset, VertexEncoding encoding,
                       const Bounds& bounds, std::span<float> out) const {
  return DecodeField(normals ? Kind::kNormals : Kind::kPositions, offset, encoding, bounds, out);
}

Status RawPart::DecodeTangents(std::size_t offset, VertexEncoding encoding,
                               std::span<float> out) const {
  return DecodeField(Kind::kTangents, offset, encoding, Bounds{}, out);
}

Status RawPart::DecodeField(Kind kind, std::size_t offset, VertexEncoding encoding,
                            const Bounds& bounds, std::span<float> out) const {
  const Field& f = kind == Kind::kPositions ? positions_
                   : kind == Kind::kNormals ? normals_
                                            : tangents_;
  const char* name = kind == Kind::kPositions ? "positions"
                     : kind == Kind::kNormals ? "normals"
                                              : "tangents";
  const std::size_t group = kind == Kind::kTangents ? kValuesPerTangent : kValuesPerVertex;
  const std::size_t per_value = EncodedBytesPerValue(encoding);
  const std::size_t per_triple = group * per_value;  // one vertex's values
  const std::size_t size = out.size() * per_value;
  if (offset + size > f.size || offset % per_triple != 0 || out.size() % group != 0) {
    return Internal(
        fmt::format("{}: bytes [{}, +{}) are not whole vertices inside the {} "
                    "received",
                    name, offset, size, f.size));
  }
  if (size == 0) return Status::Ok();
  const auto decode = [&](const std::byte* bytes, std::size_t n, std::size_t first_value) {
    const std::span<const std::byte> in(bytes, n);
    const std::span<float> into = out.subspan(first_value, n / per_value);
    switch (kind) {
      case Kind::kPositions:
        return DecodePositions(encoding, in, bounds, into);
      case Kind::kNormals:
        return DecodeNormals(encoding, in, into);
      case Kind::kTangents:
        break;
    }
    return skinserve::DecodeTangents(encoding, in, into);
  };
  // The field's bytes slice by slice; a vertex cut by a slice boundary goes through
  // `carry` (the decoders' per-axis pattern starts at x).
  std::byte carry[16];
  std::size_t carried = 0, decoded = 0;  // values written to `out`
  std::size_t at = f.offset + offset;
  const std::size_t end = at + size;
  auto slice = std::upper_bound(starts_.begin(), starts_.end(), at) - 1;
  for (std::size_t i = slice - starts_.begin(); at < end && i < slices_.size(); ++i) {
    const auto* data = reinterpret_cast<const std::byte*>(slices_[i].begin());
    std::size_t from = at - starts_[i];
    std::size_t n = std::min(slices_[i].size() - from, end - at);
    at += n;
    if (carried > 0) {
      const std::size_t take = std::min(per_triple - carried, n);
      std::memcpy(carry + carried, data + from, take);
      carried += take;
      from += take;
      n -= take;
      if (carried == per_triple) {
        if (Status s = decode(carry, per_triple, decoded); !s.ok()) return s;
        decoded += group;
        carried = 0;
      }
    }
    const std::size_t whole = n / per_triple * per_triple;
    if (whole > 0) {
      if (Status s = decode(data + from, whole, decoded); !s.ok()) return s;
      decoded += whole / per_value;
    }
    std::memcpy(carry + carried, data + from + whole, n - whole);
    carried += n - whole;
  }
  if (decoded != out.size()) {
    return Internal(
        fmt::format("{}: {} of {} values in the received bytes", name, decoded, out.size()));
  }
  return Status::Ok();
}

}  // namespace skinserve::wire
