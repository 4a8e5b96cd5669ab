#include "skin_request_reader.h"

#include <fmt/format.h>
#include <google/protobuf/io/coded_stream.h>
#include <google/protobuf/wire_format_lite.h>
#include <grpcpp/impl/codegen/proto_utils.h>
#include <grpcpp/support/proto_buffer_reader.h>

namespace skinserve::server {
namespace {

using google::protobuf::internal::WireFormatLite;
using google::protobuf::io::CodedInputStream;

// SkinRequest's field numbers that the walk looks at (proto/skinserve/v1/skinning.proto).
constexpr int kFrameField = 3;
constexpr int kMorphTargetsField = 12;
constexpr int kMorphWeightsField = 13;
constexpr int kInstanceMorphWeightsField = 14;
// MorphWeights' fields.
constexpr int kTargetsField = 1;
constexpr int kWeightsField = 2;

// Protobuf keeps a repeated scalar in an array that doubles as it grows: 8 bytes a value
// bound its 4-byte elements. A message entry costs its object and its pointer.
constexpr uint64_t kBytesPerRepeatedValue = 8;
constexpr uint64_t kBytesPerMessageEntry = sizeof(v1::MorphWeights) + 2 * sizeof(void*);
// The request's own objects: the message, its output region and the string objects of
// its four string fields (their bytes count in the wire size).
constexpr uint64_t kBytesPerRequest =
    sizeof(v1::SkinRequest) + sizeof(v1::OutputRegion) + 4 * 2 * sizeof(std::string);

// The values of one occurrence of a repeated uint32 or float field: packed (a run of
// varints or fixed32 values) or not (one value). False for bytes that are no such field.
bool CountValues(CodedInputStream* in, uint32_t tag, bool fixed32, uint64_t* values) {
  const auto type = WireFormatLite::GetTagWireType(tag);
  if (type != WireFormatLite::WIRETYPE_LENGTH_DELIMITED) {
    *values += 1;
    return WireFormatLite::SkipField(in, tag);
  }
  uint32_t length = 0;
  if (!in->ReadVarint32(&length)) return false;
  if (fixed32) {
    *values += length / 4;
    return length % 4 == 0 && in->Skip(static_cast<int>(length));
  }
  const CodedInputStream::Limit limit = in->PushLimit(static_cast<int>(length));
  uint32_t ignored = 0;
  while (in->BytesUntilLimit() > 0) {
    if (!in->ReadVarint32(&ignored)) return false;
    *values += 1;
  }
  in->PopLimit(limit);
  return true;
}

Status OverLimit(const std::string& field, uint64_t count, uint64_t limit, const char* why) {
  return InvalidArgument(
      fmt::format("{} has {} entries; at most {} ({})", field, count, limit, why));
}

const Status& NotASkinRequest() {
  static const Status status =
      InvalidArgument("the request is not a valid skinserve.v1.SkinRequest");
  return status;
}

const Status& Malformed(SkinRequestScan* scan) {
  scan->malformed = true;
  return NotASkinRequest();
}

// One MorphWeights entry of instance_morph_weights: its lists counted against the limit.
Status ScanMorphWeights(CodedInputStream* in, uint32_t entry, const SkinRequestLimits& limits,
                        uint64_t* values, SkinRequestScan* scan) {
  uint32_t length = 0;
  if (!in->ReadVarint32(&length)) return Malformed(scan);
  const CodedInputStream::Limit limit = in->PushLimit(static_cast<int>(length));
  uint64_t targets = 0, weights = 0;
  while (uint32_t tag = in->ReadTag()) {
    const int field = WireFormatLite::GetTagFieldNumber(tag);
    const bool ok = field == kTargetsField   ? CountValues(in, tag, false, &targets)
                    : field == kWeightsField ? CountValues(in, tag, true, &weights)
                                             : WireFormatLite::SkipField(in, tag);
    if (!ok) return Malformed(scan);
  }
  if (!in->ConsumedEntireMessage()) return Malformed(scan);
  in->PopLimit(limit);
  for (const auto& [name, count] : {std::pair{"targets", targets}, std::pair{"weights", weights}}) {
    if (count > limits.max_morph_weights) {
      return OverLimit(fmt::format("instance_morph_weights[{}].{}", entry, name), count,
                       limits.max_morph_weights, "a mesh's morph targets");
    }
  }
  *values += targets + weights;
  return Status::Ok();
}

}  // namespace

Status ScanSkinRequest(grpc::ByteBuffer* bytes, const SkinRequestLimits& limits,
                       SkinRequestScan* scan) {
  *scan = {};
  grpc::ProtoBufferReader reader(bytes);
  CodedInputStream in(&reader);
  uint64_t targets = 0, weights = 0, entries = 0, entry_values = 0;
  while (uint32_t tag = in.ReadTag()) {
    const int field = WireFormatLite::GetTagFieldNumber(tag);
    bool ok = true;
    if (field == kFrameField &&
        WireFormatLite::GetTagWireType(tag) == WireFormatLite::WIRETYPE_VARINT) {
      ok = in.ReadVarint64(&scan->frame);
    } else if (field == kMorphTargetsField) {
      ok = CountValues(&in, tag, false, &targets);
    } else if (field == kMorphWeightsField) {
      ok = CountValues(&in, tag, true, &weights);
    } else if (field == kInstanceMorphWeightsField &&
               WireFormatLite::GetTagWireType(tag) == WireFormatLite::WIRETYPE_LENGTH_DELIMITED) {
      if (++entries > limits.max_instances) {  // counted no further: the rest is not read
        return InvalidArgument(fmt::format(
            "instance_morph_weights has more than {} entries (one per instance of a crowd, and "
            "a request has at most {} instances)",
            limits.max_instances, limits.max_instances));
      }
      if (Status s = ScanMorphWeights(&in, static_cast<uint32_t>(entries - 1), limits,
                                      &entry_values, scan);
          !s.ok()) {
        return s;
      }
    } else {
      ok = WireFormatLite::SkipField(&in, tag);
    }
    if (!ok) return Malformed(scan);
  }
  if (!in.ConsumedEntireMessage()) return Malformed(scan);
  for (const auto& [name, count] :
       {std::pair{"morph_targets", targets}, std::pair{"morph_weights", weights}}) {
    if (count > limits.max_morph_weights) {
      return OverLimit(name, count, limits.max_morph_weights, "a mesh's morph targets");
    }
  }
  scan->parsed_bytes = kBytesPerRequest + bytes->Length() +
                       kBytesPerRepeatedValue * (targets + weights + entry_values) +
                       kBytesPerMessageEntry * entries;
  return Status::Ok();
}

Status SkinRequestReader::Read(grpc::ByteBuffer* bytes) {
  if (Status s = ScanSkinRequest(bytes, limits_, &scan_); !s.ok()) {
    bytes->Clear();
    return s;
  }
  if (scan_.parsed_bytes > charged_) {
    if (Status s = budget_->TryCharge(scan_.parsed_bytes - charged_); !s.ok()) {
      bytes->Clear();
      return s;
    }
    charged_ = scan_.parsed_bytes;
  }
  if (!grpc::SerializationTraits<v1::SkinRequest>::Deserialize(bytes, &request_).ok()) {
    scan_.malformed = true;
    return NotASkinRequest();
  }
  return Status::Ok();
}

void SkinRequestReader::Trim() {
  if (charged_ <= kKeptRequestBytes) return;
  v1::SkinRequest().Swap(&request_);  // the temporary takes the large storage with it
  budget_->Release(charged_);
  charged_ = 0;
}

}  // namespace skinserve::server
