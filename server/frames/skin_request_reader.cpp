#include "frames/skin_request_reader.h"

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
constexpr int kCharactersField = 16;
constexpr int kPoseField = 17;
// Pose's layers, and how many a pose may hold (animation::kMaxBlendLayers; PoseEvaluator
// names the same limit).
constexpr int kPoseLayersField = 2;
constexpr uint64_t kMaxPoseLayers = 8;
// MorphWeights' fields.
constexpr int kTargetsField = 1;
constexpr int kWeightsField = 2;

// Protobuf keeps a repeated scalar in an array that doubles as it grows: 8 bytes a value
// bound its 4-byte elements. A message entry costs its object and its pointer.
constexpr uint64_t kBytesPerRepeatedValue = 8;
constexpr uint64_t kBytesPerMessageEntry = sizeof(v1::MorphWeights) + 2 * sizeof(void*);
// A pose's layer: its object, its pointer and its clip id's string object; the pose itself.
constexpr uint64_t kBytesPerPoseLayer =
    sizeof(v1::PoseLayer) + sizeof(std::string) + 2 * sizeof(void*);
constexpr uint64_t kBytesPerPose = sizeof(v1::Pose) + sizeof(std::string);
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

// Where in a tick a field is: the character's index (and a nested character's), for errors.
struct Where {
  int64_t character = -1, nested = -1;
  std::string Name(const std::string& field) const {
    if (character < 0) return field;
    if (nested < 0) return fmt::format("characters[{}].{}", character, field);
    return fmt::format("characters[{}].characters[{}].{}", character, nested, field);
  }
};

// One MorphWeights entry of instance_morph_weights: its lists counted against the limit.
Status ScanMorphWeights(CodedInputStream* in, uint32_t entry, const SkinRequestLimits& limits,
                        const Where& where, uint64_t* values, SkinRequestScan* scan) {
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
      return OverLimit(where.Name(fmt::format("instance_morph_weights[{}].{}", entry, name)), count,
                       limits.max_morph_weights, "a mesh's morph targets");
    }
  }
  *values += targets + weights;
  return Status::Ok();
}

// What the walk counted, for the bound of the parsed size.
struct Counts {
  uint64_t values = 0;      // repeated scalar values
  uint64_t entries = 0;     // MorphWeights entries
  uint64_t characters = 0;  // nested SkinRequests, at every depth
  uint64_t poses = 0;       // Pose messages and their layers
  uint64_t pose_layers = 0;
};

// A Pose (SkinRequest.pose): its layers counted against kMaxPoseLayers.
Status ScanPose(CodedInputStream* in, const Where& where, SkinRequestScan* scan, Counts* counts) {
  uint32_t length = 0;
  if (!in->ReadVarint32(&length)) return Malformed(scan);
  const CodedInputStream::Limit limit = in->PushLimit(static_cast<int>(length));
  uint64_t layers = 0;
  while (uint32_t tag = in->ReadTag()) {
    if (WireFormatLite::GetTagFieldNumber(tag) == kPoseLayersField && ++layers > kMaxPoseLayers) {
      return InvalidArgument(fmt::format("{} has more than {} entries; at most {} are blended",
                                         where.Name("pose.layers"), kMaxPoseLayers,
                                         kMaxPoseLayers));
    }
    if (!WireFormatLite::SkipField(in, tag)) return Malformed(scan);
  }
  if (!in->ConsumedEntireMessage()) return Malformed(scan);
  in->PopLimit(limit);
  counts->poses += 1;
  counts->pose_layers += layers;
  return Status::Ok();
}

Status ScanFields(CodedInputStream* in, const SkinRequestLimits& limits, const Where& where,
                  SkinRequestScan* scan, Counts* counts);

// One entry of `characters`: a SkinRequest of its own, counted as the request is. Ticks do
// not nest: a character's own characters are counted (that character fails alone when
// prepared), and theirs refuse the request.
Status ScanCharacter(CodedInputStream* in, const SkinRequestLimits& limits, const Where& where,
                     SkinRequestScan* scan, Counts* counts) {
  if (++counts->characters > limits.max_tick_characters) {  // the rest is not read
    return ResourceExhausted(fmt::format(
        "the tick has more than {} characters (all of them counted, nested ones too); at most "
        "{} (--max-tick-characters)",
        limits.max_tick_characters, limits.max_tick_characters));
  }
  uint32_t length = 0;
  if (!in->ReadVarint32(&length)) return Malformed(scan);
  const CodedInputStream::Limit limit = in->PushLimit(static_cast<int>(length));
  if (Status s = ScanFields(in, limits, where, scan, counts); !s.ok()) return s;
  if (!in->ConsumedEntireMessage()) return Malformed(scan);
  in->PopLimit(limit);
  return Status::Ok();
}

// The fields of a SkinRequest (the request's, or a character's: `where`).
Status ScanFields(CodedInputStream* in, const SkinRequestLimits& limits, const Where& where,
                  SkinRequestScan* scan, Counts* counts) {
  const bool top = where.character < 0;
  uint64_t targets = 0, weights = 0, entries = 0, characters = 0;
  while (uint32_t tag = in->ReadTag()) {
    const int field = WireFormatLite::GetTagFieldNumber(tag);
    const bool delimited =
        WireFormatLite::GetTagWireType(tag) == WireFormatLite::WIRETYPE_LENGTH_DELIMITED;
    bool ok = true;
    if (field == kFrameField && top &&
        WireFormatLite::GetTagWireType(tag) == WireFormatLite::WIRETYPE_VARINT) {
      ok = in->ReadVarint64(&scan->frame);
    } else if (field == kMorphTargetsField) {
      ok = CountValues(in, tag, false, &targets);
    } else if (field == kMorphWeightsField) {
      ok = CountValues(in, tag, true, &weights);
    } else if (field == kInstanceMorphWeightsField && delimited) {
      if (++entries > limits.max_instances) {  // counted no further: the rest is not read
        return InvalidArgument(fmt::format(
            "{} has more than {} entries (one per instance of a crowd, and a request has at "
            "most {} instances)",
            where.Name("instance_morph_weights"), limits.max_instances, limits.max_instances));
      }
      if (Status s = ScanMorphWeights(in, static_cast<uint32_t>(entries - 1), limits, where,
                                      &counts->values, scan);
          !s.ok()) {
        return s;
      }
    } else if (field == kCharactersField && delimited) {
      if (where.nested >= 0) {  // a character's character's characters: not read
        return InvalidArgument(
            fmt::format("{} is set: ticks do not nest", where.Name("characters")));
      }
      const Where inner = top ? Where{.character = static_cast<int64_t>(characters++)}
                              : Where{where.character, static_cast<int64_t>(characters++)};
      if (Status s = ScanCharacter(in, limits, inner, scan, counts); !s.ok()) return s;
    } else if (field == kPoseField && delimited) {
      if (Status s = ScanPose(in, where, scan, counts); !s.ok()) return s;
    } else {
      ok = WireFormatLite::SkipField(in, tag);
    }
    if (!ok) return Malformed(scan);
  }
  for (const auto& [name, count] :
       {std::pair{"morph_targets", targets}, std::pair{"morph_weights", weights}}) {
    if (count > limits.max_morph_weights) {
      return OverLimit(where.Name(name), count, limits.max_morph_weights, "a mesh's morph targets");
    }
  }
  counts->values += targets + weights;
  counts->entries += entries;
  return Status::Ok();
}

}  // namespace

Status ScanSkinRequest(grpc::ByteBuffer* bytes, const SkinRequestLimits& limits,
                       SkinRequestScan* scan) {
  *scan = {};
  grpc::ProtoBufferReader reader(bytes);
  CodedInputStream in(&reader);
  Counts counts;
  if (Status s = ScanFields(&in, limits, Where{}, scan, &counts); !s.ok()) return s;
  if (!in.ConsumedEntireMessage()) return Malformed(scan);
  scan->characters = counts.characters;
  const uint64_t size = bytes->Length();
  if (counts.characters > 0 && size > limits.max_tick_bytes) {
    return ResourceExhausted(
        fmt::format("the tick's request holds {} bytes; at most {} (--max-tick-bytes)", size,
                    limits.max_tick_bytes));
  }
  if (counts.characters == 0 && size > kMaxFrameRequestBytes) {
    return ResourceExhausted(fmt::format(
        "the request holds {} bytes; at most {} for one frame (gRPC's default message limit; a "
        "tick of many characters may hold up to the server's --max-tick-bytes)",
        size, kMaxFrameRequestBytes));
  }
  scan->parsed_bytes = kBytesPerRequest * (1 + counts.characters) + size +
                       kBytesPerRepeatedValue * counts.values +
                       kBytesPerMessageEntry * (counts.entries + counts.characters) +
                       kBytesPerPose * counts.poses + kBytesPerPoseLayer * counts.pose_layers;
  return Status::Ok();
}

SkinRequestLimits WithMaxInstances(SkinRequestLimits limits, const Engine* engine) {
  if (engine != nullptr) limits.max_instances = engine->options().max_instances;
  return limits;
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
