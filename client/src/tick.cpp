#include "skinserve/client/tick.h"

#include <fmt/format.h>

#include <algorithm>
#include <set>

#include "skinserve/client/lost_upload.h"

namespace skinserve::client {
namespace {

Status FromPartError(const v1::FrameError& error) {
  return wire::FromGrpc(grpc::Status(static_cast<grpc::StatusCode>(error.code()), error.message()));
}

void ClearArrays(FrameResult* result) {
  result->positions.clear();  // keeps the capacity for the next tick
  result->normals.clear();
  result->tangents.clear();
  result->bounds.clear();
  result->region_positions = result->region_normals = result->region_tangents = {};
}

void CharacterToWire(const TickCharacter& c, uint64_t slot_offset, v1::SkinRequest* request) {
  const SkinOptions& o = c.options;
  request->set_mesh_id(c.mesh_id);
  request->set_backend(o.backend);
  wire::EncodeFloats(c.palette, request->mutable_palette());
  request->set_want_normals(o.want_normals);
  request->set_want_tangents(o.want_tangents);
  request->set_method(wire::ToWire(o.method));
  request->set_encoding(static_cast<v1::Encoding>(o.encoding));
  request->set_instances(o.instances);
  request->set_pack_instances(true);  // FrameAssembler takes packed parts
  request->set_early_parts(o.early_parts);
  wire::MorphWeightsToWire(o.morph_weights, request);
  wire::InstanceMorphWeightsToWire(o.instance_morph_weights, request);
  PoseToWire(o.pose, request);
  if (o.output.enabled()) {
    request->mutable_output()->set_region(o.output.name);
    request->mutable_output()->set_offset(o.output.offset + slot_offset);
  }
}

}  // namespace

std::size_t Tick::Add(const std::string& mesh_id, std::span<const float> palette,
                      const SkinOptions& options) {
  if (size_ == characters_.size()) characters_.emplace_back();
  TickCharacter& c = characters_[size_];
  c.mesh_id.assign(mesh_id);  // keeps the kept character's capacity
  c.palette = palette;
  c.options = options;
  return size_++;
}

std::size_t Tick::AddPose(const std::string& mesh_id, const Pose& pose, SkinOptions options) {
  options.pose = pose;
  return Add(mesh_id, {}, options);
}

void Tick::ToWire(v1::SkinRequest* request, uint64_t slot_offset) const {
  request->Clear();  // keeps the characters' messages for reuse by Add
  request->set_frame(frame_);
  for (const TickCharacter& c : characters()) {
    CharacterToWire(c, slot_offset, request->add_characters());
  }
}

std::size_t TickResult::failed() const {
  return static_cast<std::size_t>(std::count_if(
      characters.begin(), characters.end(), [](const FrameResult& r) { return !r.status.ok(); }));
}

TickAssembler::TickAssembler(const Tick& tick, TickResult* result)
    : tick_(tick), result_(result), complete_(tick.size(), 0) {
  result->frame = tick.frame();
  result->status = Status::Ok();
  result->characters.resize(tick.size());  // keeps each kept result's vectors
  assemblers_.reserve(tick.size());
  for (std::size_t i = 0; i < tick.size(); ++i) {
    assemblers_.emplace_back(&tick.character(i).options.output);
    assemblers_.back().set_in_tick();
    FrameResult& r = result->characters[i];
    r.frame = tick.frame();
    r.status = Status::Ok();
    ClearArrays(&r);
  }
}

void TickAssembler::FailTick(Status status) {
  failed_ = true;
  result_->status = status;
  for (FrameResult& r : result_->characters) {
    r.status = status;
    ClearArrays(&r);
  }
}

bool TickAssembler::Add(const grpc::ByteBuffer& bytes, RawPart* reader) {
  if (!reader->Parse(bytes)) {
    FailTick(Internal(fmt::format("tick {}: a part of {} bytes is not a skinserve.v1.SkinResponse",
                                  tick_.frame(), bytes.Length())));
    return true;  // nothing more of this tick can be trusted
  }
  const v1::SkinResponse& part = reader->header();
  if (failed_) return part.last();
  if (part.frame() != tick_.frame()) {
    FailTick(
        Internal(fmt::format("tick {}: a part of frame {} came", tick_.frame(), part.frame())));
    return part.last();
  }
  if (part.has_tick() || part.last()) {
    if (part.has_error()) {  // refused whole (a limit, the tick's own fields)
      FailTick(FromPartError(part.error()));
      return true;
    }
    return Finish(part);
  }
  const uint32_t c = part.character();
  if (c >= tick_.size() || complete_[c]) {
    FailTick(Internal(
        fmt::format("tick {}: a part of character {} came, which the tick {}", tick_.frame(), c,
                    c >= tick_.size() ? fmt::format("does not have ({} characters)", tick_.size())
                                      : std::string("had complete already"))));
    return false;
  }
  complete_[c] = assemblers_[c].Add(*reader, &result_->characters[c]) ? 1 : 0;
  return false;
}

bool TickAssembler::Finish(const v1::SkinResponse& final_part) {
  const auto& headers = final_part.tick().characters();
  if (headers.size() != static_cast<int>(tick_.size())) {
    FailTick(
        Internal(fmt::format("tick {}: the final part has {} character headers for {} "
                             "characters",
                             tick_.frame(), headers.size(), tick_.size())));
    return true;
  }
  for (std::size_t i = 0; i < tick_.size(); ++i) {
    const v1::SkinResponse& header = headers[static_cast<int>(i)];
    FrameResult& r = result_->characters[i];
    if (header.character() != i) {
      r.status = Internal(fmt::format("tick {}: header {} names character {}", tick_.frame(), i,
                                      header.character()));
    } else if (header.has_error()) {
      r.status = FromPartError(header.error());  // drops any parts of it before
    } else if (header.has_region_write()) {
      assemblers_[i].Add(header, &r);  // checks its ranges against the mapping
      continue;
    } else if (!complete_[i]) {
      r.status =
          Internal(fmt::format("tick {}: character {} was not answered in full", tick_.frame(), i));
    } else {
      r.timing = header.timing();
    }
    if (!r.status.ok()) ClearArrays(&r);
  }
  return true;
}

Status SkinClient::SkinTick(const Tick& tick, TickResult* result) {
  v1::SkinRequest request;
  tick.ToWire(&request);
  const auto once = [&] {
    grpc::ClientContext context;
    SetDeadline(&context, limits_.deadline);
    auto reader = SkinRaw(&context, request);
    TickAssembler assembler(tick, result);
    RawPart part;
    grpc::ByteBuffer bytes;
    bool complete = false;
    while (reader->Read(&bytes)) {
      if (!complete) complete = assembler.Add(bytes, &part);
    }
    grpc::Status status = reader->Finish();
    if (!status.ok()) {
      for (FrameResult& r : result->characters) {
        r.status = wire::FromGrpc(status);
        ClearArrays(&r);
      }
      result->status = wire::FromGrpc(status);
    } else if (!complete) {
      result->status = Internal("the server ended the tick without its final part");
    }
    return result->status;
  };
  Status status = once();
  if (!status.ok()) return status;
  // Characters whose mesh (or pose's skeleton or clip) the server lost: upload those this
  // client knows, then once more.
  std::set<LostUpload> lost;
  for (std::size_t i = 0; i < tick.size(); ++i) {
    const Status& s = result->characters[i].status;
    if (s.code() == StatusCode::kNotFound) lost.insert(LostUploadOf(s, tick.character(i).mesh_id));
  }
  bool reuploaded = false;
  for (const LostUpload& upload : lost) {
    if (Status s = Reupload(upload); s.ok()) {
      reuploaded = true;
    } else {
      for (std::size_t i = 0; i < tick.size(); ++i) {
        FrameResult& r = result->characters[i];
        if (r.status.code() == StatusCode::kNotFound &&
            LostUploadOf(r.status, tick.character(i).mesh_id) == upload) {
          r.status = Status(r.status.code(), fmt::format("{}; re-uploading it failed: {}",
                                                         r.status.message(), s.ToString()));
        }
      }
    }
  }
  return reuploaded ? once() : status;
}

}  // namespace skinserve::client
