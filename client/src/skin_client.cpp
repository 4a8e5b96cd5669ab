#include "skinserve/client/skin_client.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <thread>

#include "skinserve/client/channel.h"
#include "skinserve/wire/region_layout.h"

namespace skinserve::client {

using wire::FromWire;

bool FrameAssembler::Fail(const v1::SkinResponse& part, FrameResult* result, Status status) {
  failed_ = true;
  result->status = std::move(status);
  result->positions.clear();  // keeps the capacity for the next frame
  result->normals.clear();
  result->tangents.clear();
  result->bounds.clear();
  result->region_positions = result->region_normals = result->region_tangents = {};
  return part.last();
}

bool FrameAssembler::AddRegionPart(const v1::SkinResponse& part, FrameResult* result) {
  const v1::RegionWrite& write = part.region_write();
  const auto fail = [&](const std::string& why) {
    return Fail(part, result, Internal(fmt::format("frame {}: {}", part.frame(), why)));
  };
  if (output_ == nullptr || !output_->enabled() || write.region() != output_->name) {
    return fail(
        fmt::format("answered in region '{}', which the frame did not name", write.region()));
  }
  const uint32_t instances = std::max(part.instances(), 1u);
  const auto encoding = static_cast<VertexEncoding>(part.encoding());
  const uint64_t instance_bytes =
      uint64_t{part.total_vertices()} * 3 * EncodedBytesPerValue(encoding);
  const uint64_t array_bytes = instance_bytes * instances;
  const bool normals = write.normals_offset() != write.positions_offset();
  const bool tangents = write.tangent_instance_bytes() > 0;
  const std::span<const std::byte> mapping = output_->region->bytes();
  // Checked before any offset is added up: a server's offset near 2^64 must not wrap into
  // a range that seems to fit (and then be read outside the mapping).
  if (!wire::LayoutFitsRegion(write.positions_offset(), part.total_vertices(), instances, encoding,
                              normals, tangents, mapping.size())) {
    return fail(fmt::format(
        "region '{}': the answer's range ({} x {} vertices in {} from offset {}{}) does not fit "
        "the region's {} bytes",
        write.region(), instances, part.total_vertices(), VertexEncodingName(encoding),
        write.positions_offset(),
        tangents ? " with normals and tangents" : (normals ? " with normals" : ""),
        mapping.size()));
  }
  const wire::RegionLayout layout = wire::LayoutInRegion(
      write.positions_offset(), part.total_vertices(), instances, encoding, normals, tangents);
  if (!part.last() || write.instance_bytes() != instance_bytes ||
      write.normals_offset() != layout.normals_offset || write.end_offset() != layout.end_offset ||
      (tangents && (write.tangents_offset() != layout.tangents_offset ||
                    write.tangent_instance_bytes() != layout.tangent_instance_bytes)) ||
      layout.end_offset > mapping.size()) {
    return fail(fmt::format(
        "region '{}': the answer's ranges (positions at {}, normals at {}, {} bytes per "
        "instance, end {}) do not fit {} x {} vertices in {} within the region's {} bytes",
        write.region(), write.positions_offset(), write.normals_offset(), write.instance_bytes(),
        write.end_offset(), instances, part.total_vertices(), VertexEncodingName(encoding),
        mapping.size()));
  }
  if (QuantizedToBox(encoding) && part.instance_bounds_size() != static_cast<int>(instances)) {
    return fail(
        fmt::format("{} instances but {} instance_bounds", instances, part.instance_bounds_size()));
  }
  result->vertices = part.total_vertices();
  result->instances = instances;
  result->encoding = encoding;
  result->positions.clear();
  result->normals.clear();
  result->tangents.clear();
  result->bounds.assign(instances, Bounds{});
  for (uint32_t k = 0; QuantizedToBox(encoding) && k < instances; ++k) {
    result->bounds[k] = FromWire(part.instance_bounds(static_cast<int>(k)));
  }
  result->region_positions = mapping.subspan(layout.positions_offset, array_bytes);
  result->region_normals =
      normals ? mapping.subspan(layout.normals_offset, array_bytes) : std::span<const std::byte>();
  result->region_tangents =
      tangents ? mapping.subspan(layout.tangents_offset, layout.tangent_instance_bytes * instances)
               : std::span<const std::byte>();
  return true;
}

Status DecodeRegionFrame(FrameResult* result) {
  if (!result->in_region()) return Status::Ok();
  const std::size_t count = 3ull * result->vertices;
  const std::size_t instance_bytes = count * EncodedBytesPerValue(result->encoding);
  const bool normals = !result->region_normals.empty();
  const std::size_t tangent_count = kValuesPerTangent * result->vertices;
  const std::size_t tangent_bytes = EncodedTangentBytes(result->encoding, result->vertices);
  const bool tangents = !result->region_tangents.empty();
  result->positions.resize(count * result->instances);
  result->normals.resize(normals ? count * result->instances : 0);
  result->tangents.resize(tangents ? tangent_count * result->instances : 0);
  for (uint32_t k = 0; k < result->instances; ++k) {
    const Bounds& bounds = result->bounds[k];
    if (Status s = DecodePositions(
            result->encoding, result->region_positions.subspan(k * instance_bytes, instance_bytes),
            bounds, std::span<float>(result->positions).subspan(k * count, count));
        !s.ok()) {
      return s;
    }
    if (!normals) continue;
    if (Status s = DecodeNormals(result->encoding,
                                 result->region_normals.subspan(k * instance_bytes, instance_bytes),
                                 std::span<float>(result->normals).subspan(k * count, count));
        !s.ok()) {
      return s;
    }
    if (!tangents) continue;
    if (Status s = DecodeTangents(
            result->encoding, result->region_tangents.subspan(k * tangent_bytes, tangent_bytes),
            std::span<float>(result->tangents).subspan(k * tangent_count, tangent_count));
        !s.ok()) {
      return s;
    }
  }
  return Status::Ok();
}

namespace {

Status PartError(const v1::SkinResponse& part) {
  return wire::FromGrpc(
      grpc::Status(static_cast<grpc::StatusCode>(part.error().code()), part.error().message()));
}

// A frame's first part that ends it: the server's error, or an encoding this client does not
// know.
Status FirstPartProblem(const v1::SkinResponse& part) {
  if (part.has_error()) return PartError(part);
  if (!v1::Encoding_IsValid(part.encoding())) {
    return Internal(fmt::format("frame {}: unknown encoding {}", part.frame(),
                                static_cast<int>(part.encoding())));
  }
  return Status::Ok();
}

Status VertexLimitProblem(const v1::SkinResponse& part, uint32_t instances) {
  const uint64_t vertices = uint64_t{instances} * part.total_vertices();
  if (vertices <= kMaxFrameVertices) return Status::Ok();
  return Internal(
      fmt::format("frame {}: {} instances x {} vertices is more than the client accepts ({})",
                  part.frame(), instances, part.total_vertices(), kMaxFrameVertices));
}

// Where a part lies in its frame, for messages.
std::string PartPlace(const v1::SkinResponse& part) {
  return fmt::format("frame {}, instance {}, vertices [{}, +{})", part.frame(), part.instance(),
                     part.first_vertex(), part.vertex_count());
}

// A part's shape against its frame's first part's (`normals`, `tangents`: the first part had
// them; `sizes`: this part's bytes of normals and tangents).
Status ShapeProblem(const v1::SkinResponse& part, const FrameResult& frame, bool normals,
                    bool tangents, std::size_t normals_size, std::size_t tangents_size) {
  const uint32_t instances = std::max(part.instances(), 1u);
  const auto encoding = static_cast<VertexEncoding>(part.encoding());
  if (part.frame() == frame.frame && part.total_vertices() == frame.vertices &&
      instances == frame.instances && encoding == frame.encoding && normals == (normals_size > 0) &&
      tangents == (tangents_size > 0)) {
    return Status::Ok();
  }
  return Internal(fmt::format(
      "{}: the part does not match its frame's first part (frame {}, {} x {} vertices, {}, "
      "normals {}, tangents {})",
      PartPlace(part), frame.frame, frame.instances, frame.vertices,
      VertexEncodingName(frame.encoding), normals, tangents));
}

// A part's range: the next of its frame (instance `next_instance`, vertex `next_vertex`);
// a packed part (`packed` instances) holds whole instances.
Status RangeProblem(const v1::SkinResponse& part, const FrameResult& frame, uint32_t packed,
                    uint32_t next_instance, uint32_t next_vertex) {
  if (part.instance() != next_instance || part.first_vertex() != next_vertex ||
      part.vertex_count() == 0 ||
      uint64_t{part.first_vertex()} + part.vertex_count() > frame.vertices ||
      (packed > 1 && (part.first_vertex() != 0 || part.vertex_count() != frame.vertices ||
                      uint64_t{part.instance()} + packed > frame.instances))) {
    return Internal(fmt::format(
        "{}: out of order or out of range: instance {} vertex {} was due, {} vertices per "
        "instance, {} instance(s) in the part of {}",
        PartPlace(part), next_instance, next_vertex, frame.vertices, packed, frame.instances));
  }
  if (packed > 1 && QuantizedToBox(frame.encoding) &&
      part.instance_bounds_size() != static_cast<int>(packed)) {
    return Internal(fmt::format("{}: {} instances in the part but {} instance_bounds",
                                PartPlace(part), packed, part.instance_bounds_size()));
  }
  return Status::Ok();
}

// Each vertex field holds exactly the part's vertices.
Status SizeProblem(const v1::SkinResponse& part, VertexEncoding encoding, uint32_t packed,
                   bool normals, bool tangents, std::size_t positions_size,
                   std::size_t normals_size, std::size_t tangents_size) {
  const std::size_t expected = packed * 3ull * part.vertex_count() * EncodedBytesPerValue(encoding);
  if (positions_size != expected || (normals && normals_size != expected)) {
    const bool positions = positions_size != expected;
    return Internal(fmt::format(
        "{}: {}: {} bytes, expected {} ({} values of {})", PartPlace(part),
        positions ? "positions" : "normals", positions ? positions_size : normals_size, expected,
        expected / EncodedBytesPerValue(encoding), VertexEncodingName(encoding)));
  }
  const std::size_t tangent_bytes =
      packed * kValuesPerTangent * part.vertex_count() * EncodedBytesPerValue(encoding);
  if (tangents && tangents_size != tangent_bytes) {
    return Internal(fmt::format("{}: tangents: {} bytes, expected {} (4 values a vertex of {})",
                                PartPlace(part), tangents_size, tangent_bytes,
                                VertexEncodingName(encoding)));
  }
  return Status::Ok();
}

// Decodes each instance of a part (checked) into the frame's arrays.
template <typename Decode>
Status DecodeInstances(const v1::SkinResponse& part, uint32_t packed, bool normals, bool tangents,
                       const Decode& decode, FrameResult* result) {
  const VertexEncoding encoding = result->encoding;
  const std::size_t count = 3ull * part.vertex_count();
  const std::size_t instance_bytes = count * EncodedBytesPerValue(encoding);
  const std::size_t tangent_count = kValuesPerTangent * part.vertex_count();
  const std::size_t tangent_instance_bytes = tangent_count * EncodedBytesPerValue(encoding);
  for (uint32_t k = 0; k < packed; ++k) {
    const uint32_t instance = part.instance() + k;
    const Bounds bounds =
        FromWire(packed > 1 && QuantizedToBox(encoding) ? part.instance_bounds(static_cast<int>(k))
                                                        : part.bounds());
    Bounds& instance_bounds = result->bounds[instance];
    if (part.first_vertex() == 0) {
      instance_bounds = bounds;
    } else if (bounds != instance_bounds) {
      return Internal(
          fmt::format("{}: bounds differ from the instance's first part", PartPlace(part)));
    }
    const std::size_t offset = 3 * (uint64_t{instance} * result->vertices + part.first_vertex());
    Status decoded = decode(0, k * instance_bytes, encoding, bounds,
                            std::span<float>(result->positions).subspan(offset, count));
    if (decoded.ok() && normals) {
      decoded = decode(1, k * instance_bytes, encoding, bounds,
                       std::span<float>(result->normals).subspan(offset, count));
    }
    if (decoded.ok() && tangents) {
      decoded = decode(2, k * tangent_instance_bytes, encoding, bounds,
                       std::span<float>(result->tangents)
                           .subspan(offset / kValuesPerVertex * kValuesPerTangent, tangent_count));
    }
    if (!decoded.ok()) return Internal(fmt::format("{}: {}", PartPlace(part), decoded.message()));
  }
  return Status::Ok();
}

// A part that ends (or does not end) the frame where it should not.
Status EndProblem(const v1::SkinResponse& part, const FrameResult& frame, uint32_t next_instance,
                  uint32_t next_vertex) {
  if (part.last() && next_instance != frame.instances) {
    return Internal(fmt::format("frame {}: ended at instance {} vertex {} of {} x {} vertices",
                                part.frame(), next_instance, next_vertex, frame.instances,
                                frame.vertices));
  }
  if (!part.last() && next_instance == frame.instances) {
    return Internal(
        fmt::format("{}: the frame is complete but the part is not marked last", PartPlace(part)));
  }
  return Status::Ok();
}

}  // namespace

// `part` is the header; `sizes` the bytes of its vertex fields.
template <typename Decode>
bool FrameAssembler::AddPart(const v1::SkinResponse& part, FieldSizes sizes, const Decode& decode,
                             FrameResult* result) {
  const uint32_t instances = std::max(part.instances(), 1u);  // 0: a server before crowds
  if (!started_) {
    started_ = true;
    result->frame = part.frame();
    result->status = Status::Ok();
    result->timing = part.timing();
    result->region_positions = result->region_normals = result->region_tangents = {};
    if (Status s = FirstPartProblem(part); !s.ok()) return Fail(part, result, std::move(s));
    if (part.has_region_write()) return AddRegionPart(part, result);
    if (Status s = VertexLimitProblem(part, instances); !s.ok()) {
      return Fail(part, result, std::move(s));
    }
    const uint64_t vertices = uint64_t{instances} * part.total_vertices();
    result->vertices = part.total_vertices();
    result->instances = instances;
    result->encoding = static_cast<VertexEncoding>(part.encoding());
    normals_ = sizes.normals > 0;
    tangents_ = sizes.tangents > 0;
    result->positions.resize(3 * vertices);  // same size as last frame: no work
    result->normals.resize(normals_ ? 3 * vertices : 0);
    result->tangents.resize(tangents_ ? 4 * vertices : 0);
    result->bounds.assign(instances, Bounds{});
  }
  if (failed_) return part.last();
  // After early parts: the frame failed, drop what came before.
  if (part.has_error()) return Fail(part, result, PartError(part));
  // Early parts (SkinRequest.early_parts): only the final part carries the timings.
  if (part.last()) result->timing = part.timing();
  // A packed part holds `packed` whole instances; else one instance's vertex range.
  const uint32_t packed = std::max(part.instance_count(), 1u);
  Status s = ShapeProblem(part, *result, normals_, tangents_, sizes.normals, sizes.tangents);
  if (s.ok()) s = RangeProblem(part, *result, packed, next_instance_, next_vertex_);
  if (s.ok()) {
    s = SizeProblem(part, result->encoding, packed, normals_, tangents_, sizes.positions,
                    sizes.normals, sizes.tangents);
  }
  if (s.ok()) s = DecodeInstances(part, packed, normals_, tangents_, decode, result);
  if (!s.ok()) return Fail(part, result, std::move(s));
  // A packed part covers its instances whole: the range ends at the last vertex too.
  next_vertex_ += part.vertex_count();
  if (next_vertex_ == result->vertices) {
    next_instance_ += packed;
    next_vertex_ = 0;
  }
  if (in_tick_) return next_instance_ == result->instances;  // the tick's final part ends it
  if (s = EndProblem(part, *result, next_instance_, next_vertex_); !s.ok()) {
    return Fail(part, result, std::move(s));
  }
  return part.last();
}

bool FrameAssembler::Add(const v1::SkinResponse& part, FrameResult* result) {
  const auto decode = [&](int field, std::size_t offset, VertexEncoding encoding,
                          const Bounds& bounds, std::span<float> out) {
    const std::string& data = field == 0   ? part.positions()
                              : field == 1 ? part.normals()
                                           : part.tangents();
    const std::span<const std::byte> bytes(reinterpret_cast<const std::byte*>(data.data()) + offset,
                                           out.size() * EncodedBytesPerValue(encoding));
    return field == 0   ? DecodePositions(encoding, bytes, bounds, out)
           : field == 1 ? DecodeNormals(encoding, bytes, out)
                        : DecodeTangents(encoding, bytes, out);
  };
  return AddPart(part, {part.positions().size(), part.normals().size(), part.tangents().size()},
                 decode, result);
}

bool FrameAssembler::Add(const grpc::ByteBuffer& bytes, RawPart* reader, FrameResult* result) {
  if (!reader->Parse(bytes)) {
    v1::SkinResponse unreadable;
    unreadable.set_last(true);  // nothing more of this frame can be trusted
    if (!started_) result->frame = 0;
    started_ = true;
    return Fail(unreadable, result,
                Internal(fmt::format("a part of {} bytes is not a skinserve.v1.SkinResponse",
                                     bytes.Length())));
  }
  return Add(*reader, result);
}

bool FrameAssembler::Add(const RawPart& part, FrameResult* result) {
  const auto decode = [&](int field, std::size_t offset, VertexEncoding encoding,
                          const Bounds& bounds, std::span<float> out) {
    return field == 2 ? part.DecodeTangents(offset, encoding, out)
                      : part.Decode(field == 1, offset, encoding, bounds, out);
  };
  return AddPart(part.header(), {part.positions_size(), part.normals_size(), part.tangents_size()},
                 decode, result);
}

SkinClient::SkinClient(std::shared_ptr<grpc::Channel> channel, const CallLimits& limits)
    : channel_(std::move(channel)),
      limits_(limits),
      stub_(v1::Skinning::NewStub(channel_)),
      stream_skin_name_(fmt::format("/{}/StreamSkin", v1::Skinning::service_full_name())),
      skin_name_(fmt::format("/{}/Skin", v1::Skinning::service_full_name())),
      stream_skin_raw_(stream_skin_name_.c_str(), grpc::internal::RpcMethod::BIDI_STREAMING,
                       channel_),
      skin_raw_(skin_name_.c_str(), grpc::internal::RpcMethod::SERVER_STREAMING, channel_) {}

void SkinClient::SetDeadline(grpc::ClientContext* context, std::chrono::milliseconds limit) {
  if (limit.count() > 0) context->set_deadline(std::chrono::system_clock::now() + limit);
}

// gRPC's public API reads typed messages only through generated stubs (or the async and
// callback generic stubs); these use the factories the generated code itself calls, with
// ByteBuffer (gRPC's own serialization of it: no copy) as the answer's type.
std::unique_ptr<SkinClient::RawStream> SkinClient::StreamSkinRaw(grpc::ClientContext* context) {
  return std::unique_ptr<RawStream>(
      grpc::internal::ClientReaderWriterFactory<v1::SkinRequest, grpc::ByteBuffer>::Create(
          channel_.get(), stream_skin_raw_, context));
}

std::unique_ptr<grpc::ClientReader<grpc::ByteBuffer>> SkinClient::SkinRaw(
    grpc::ClientContext* context, const v1::SkinRequest& request) {
  return std::unique_ptr<grpc::ClientReader<grpc::ByteBuffer>>(
      grpc::internal::ClientReaderFactory<grpc::ByteBuffer>::Create(channel_.get(), skin_raw_,
                                                                    context, request));
}

Result<v1::MeshInfo> SkinClient::Upload(const MeshArrays& arrays, const UploadOptions& options) {
  // Validate and hash locally: the id tells whether the server already has this content.
  auto mesh =
      Mesh::Create(arrays, {.limits = {.max_vertices = UINT32_MAX, .max_joints = kMaxJointsLimit},
                            .weight_policy = options.weight_policy,
                            .rest_encoding = options.rest_encoding});
  if (!mesh.ok()) return mesh.status();
  {
    std::lock_guard lock(mutex_);
    uploaded_[(*mesh)->id()] = {std::make_shared<MeshArrays>(arrays), options};
  }
  auto existing = GetMesh((*mesh)->id());
  if (existing.ok()) return existing;
  if (existing.status().code() != StatusCode::kNotFound) return existing.status();
  return SendUpload(arrays, options);
}

void SkinClient::Remember(const std::string& mesh_id, std::shared_ptr<const MeshArrays> arrays,
                          const UploadOptions& options) {
  std::lock_guard lock(mutex_);
  uploaded_[mesh_id] = {std::move(arrays), options};
}

Status SkinClient::Reupload(const std::string& mesh_id) {
  Uploaded uploaded;
  {
    std::lock_guard lock(mutex_);
    auto it = uploaded_.find(mesh_id);
    if (it == uploaded_.end()) {
      return NotFound(
          fmt::format("mesh '{}' is not on the server and this client never "
                      "uploaded it",
                      mesh_id));
    }
    uploaded = it->second;
  }
  // A mesh a server lost is lost to every stream of this process at once, and clients of
  // one process share a connection: the server's --max-uploads-per-connection may refuse
  // some of their re-uploads while the others are under way. A refused one waits, looks
  // whether the mesh is back, and tries again (about 1.3 s in all).
  auto wait = std::chrono::milliseconds(20);
  for (int attempt = 0;; ++attempt) {
    const Status sent = SendUpload(*uploaded.arrays, uploaded.options).status();
    if (sent.code() != StatusCode::kResourceExhausted || attempt == 6) return sent;
    std::this_thread::sleep_for(wait);
    wait *= 2;
    if (GetMesh(mesh_id).ok()) return Status::Ok();
  }
}

Result<v1::MeshInfo> SkinClient::SendUpload(const MeshArrays& arrays,
                                            const UploadOptions& options) {
  grpc::ClientContext context;
  SetDeadline(&context, limits_.upload_deadline);
  v1::MeshInfo info;
  auto writer = stub_->UploadMesh(&context, &info);
  v1::UploadMeshRequest request;
  v1::MeshHeader* header = request.mutable_header();
  header->set_vertex_count(arrays.vertex_count);
  header->set_influences(arrays.influences);
  header->set_joint_count(arrays.joint_count);
  header->set_has_normals(!arrays.normals.empty());
  header->set_rest_encoding(wire::ToWire(options.rest_encoding));
  header->set_weight_policy(options.weight_policy == WeightPolicy::kNormalize
                                ? v1::WEIGHT_POLICY_NORMALIZE
                                : v1::WEIGHT_POLICY_REJECT);
  header->mutable_morph_target_sizes()->Add(arrays.morph_target_sizes.begin(),
                                            arrays.morph_target_sizes.end());
  header->set_morph_normals(!arrays.morph_normal_deltas.empty());
  header->set_has_tangents(!arrays.tangents.empty());
  header->set_morph_tangents(!arrays.morph_tangent_deltas.empty());
  bool sending = writer->Write(request);
  auto send_array = [&](v1::MeshArray kind, const void* data, std::size_t count,
                        std::size_t value_size) {
    const std::size_t per_chunk = kUploadChunkBytes / value_size;
    for (std::size_t offset = 0; sending && offset < count; offset += per_chunk) {
      const std::size_t n = std::min(per_chunk, count - offset);
      v1::UploadMeshRequest chunk_request;
      v1::MeshChunk* chunk = chunk_request.mutable_chunk();
      chunk->set_array(kind);
      chunk->set_offset(offset);
      chunk->set_data(static_cast<const char*>(data) + offset * value_size, n * value_size);
      sending = writer->Write(chunk_request);
    }
  };
  send_array(v1::MESH_ARRAY_POSITIONS, arrays.positions.data(), arrays.positions.size(), 4);
  send_array(v1::MESH_ARRAY_NORMALS, arrays.normals.data(), arrays.normals.size(), 4);
  send_array(v1::MESH_ARRAY_JOINTS, arrays.joints.data(), arrays.joints.size(), 2);
  send_array(v1::MESH_ARRAY_WEIGHTS, arrays.weights.data(), arrays.weights.size(), 4);
  send_array(v1::MESH_ARRAY_MORPH_INDICES, arrays.morph_indices.data(), arrays.morph_indices.size(),
             4);
  send_array(v1::MESH_ARRAY_MORPH_POSITION_DELTAS, arrays.morph_position_deltas.data(),
             arrays.morph_position_deltas.size(), 4);
  send_array(v1::MESH_ARRAY_MORPH_NORMAL_DELTAS, arrays.morph_normal_deltas.data(),
             arrays.morph_normal_deltas.size(), 4);
  send_array(v1::MESH_ARRAY_TANGENTS, arrays.tangents.data(), arrays.tangents.size(), 4);
  send_array(v1::MESH_ARRAY_MORPH_TANGENT_DELTAS, arrays.morph_tangent_deltas.data(),
             arrays.morph_tangent_deltas.size(), 4);
  if (sending) writer->WritesDone();
  grpc::Status status = writer->Finish();
  if (!status.ok()) return wire::FromGrpc(status);
  return info;
}

Result<v1::MeshInfo> SkinClient::GetMesh(const std::string& mesh_id) {
  grpc::ClientContext context;
  SetDeadline(&context, limits_.deadline);
  v1::GetMeshRequest request;
  request.set_mesh_id(mesh_id);
  v1::MeshInfo info;
  grpc::Status status = stub_->GetMesh(&context, request, &info);
  if (!status.ok()) return wire::FromGrpc(status);
  return info;
}

Result<bool> SkinClient::DeleteMesh(const std::string& mesh_id) {
  grpc::ClientContext context;
  SetDeadline(&context, limits_.deadline);
  v1::DeleteMeshRequest request;
  request.set_mesh_id(mesh_id);
  v1::DeleteMeshResponse response;
  grpc::Status status = stub_->DeleteMesh(&context, request, &response);
  if (!status.ok()) return wire::FromGrpc(status);
  return response.deleted();
}

Result<v1::ListBackendsResponse> SkinClient::ListBackends() {
  grpc::ClientContext context;
  SetDeadline(&context, limits_.deadline);
  v1::ListBackendsResponse response;
  grpc::Status status = stub_->ListBackends(&context, v1::ListBackendsRequest(), &response);
  if (!status.ok()) return wire::FromGrpc(status);
  return response;
}

Result<v1::ServerStats> SkinClient::GetServerStats() {
  grpc::ClientContext context;
  SetDeadline(&context, limits_.deadline);
  v1::ServerStats response;
  grpc::Status status = stub_->GetServerStats(&context, v1::GetServerStatsRequest(), &response);
  if (!status.ok()) return wire::FromGrpc(status);
  return response;
}

Result<v1::RegionInfo> SkinClient::RegisterRegion(const std::string& name,
                                                  const SharedMemoryRegion& region) {
  grpc::ClientContext context;
  SetDeadline(&context, limits_.deadline);
  v1::RegisterRegionRequest request;
  request.set_name(name);
  request.set_key(region.key());
  request.set_byte_size(region.byte_size());
  v1::RegionInfo info;
  grpc::Status status = stub_->RegisterRegion(&context, request, &info);
  if (!status.ok()) return wire::FromGrpc(status);
  return info;
}

Status SkinClient::UnregisterRegion(const std::string& name) {
  grpc::ClientContext context;
  SetDeadline(&context, limits_.deadline);
  v1::UnregisterRegionRequest request;
  request.set_name(name);
  v1::UnregisterRegionResponse response;
  return wire::FromGrpc(stub_->UnregisterRegion(&context, request, &response));
}

Result<v1::ListRegionsResponse> SkinClient::ListRegions() {
  grpc::ClientContext context;
  SetDeadline(&context, limits_.deadline);
  v1::ListRegionsResponse response;
  grpc::Status status = stub_->ListRegions(&context, v1::ListRegionsRequest(), &response);
  if (!status.ok()) return wire::FromGrpc(status);
  return response;
}

Status SkinClient::SkinPose(const std::string& mesh_id, const Pose& pose, uint64_t frame,
                            SkinOptions options, FrameResult* result) {
  options.pose = pose;
  return Skin(mesh_id, {}, frame, options, result);
}

Status SkinClient::Skin(const std::string& mesh_id, const std::string& backend,
                        std::span<const float> palette, uint64_t frame, bool want_normals,
                        FrameResult* result, SkinningMethod method) {
  return Skin(mesh_id, palette, frame,
              {.backend = backend, .want_normals = want_normals, .method = method}, result);
}

Status SkinClient::Skin(const std::string& mesh_id, std::span<const float> palette, uint64_t frame,
                        const SkinOptions& options, FrameResult* result) {
  std::unique_lock lock(skin_messages_mutex_, std::try_to_lock);
  v1::SkinRequest own_request;
  RawPart own_part;
  v1::SkinRequest& request = lock.owns_lock() ? skin_request_ : own_request;
  RawPart* part = lock.owns_lock() ? &skin_part_ : &own_part;
  request.set_mesh_id(mesh_id);
  request.set_backend(options.backend);
  request.set_frame(frame);
  wire::EncodeFloats(palette, request.mutable_palette());
  request.set_want_normals(options.want_normals);
  request.set_want_tangents(options.want_tangents);
  request.set_method(wire::ToWire(options.method));
  request.set_encoding(static_cast<v1::Encoding>(options.encoding));
  request.set_instances(options.instances);
  request.set_pack_instances(true);  // FrameAssembler takes packed parts
  request.set_early_parts(options.early_parts);
  wire::MorphWeightsToWire(options.morph_weights, &request);
  wire::InstanceMorphWeightsToWire(options.instance_morph_weights, &request);
  PoseToWire(options.pose, &request);
  if (options.output.enabled()) {
    request.mutable_output()->set_region(options.output.name);
    request.mutable_output()->set_offset(options.output.offset);
  } else {
    request.clear_output();
  }
  Status status = SkinOnce(request, options.output, part, result);
  if (status.code() == StatusCode::kNotFound) {
    // The mesh, or the skeleton or a clip of the frame's pose (LostUploadOf).
    if (Status s = Reupload(LostUploadOf(status, mesh_id)); !s.ok()) {  // the NOT_FOUND, and why
      status = Status(status.code(), fmt::format("{}; re-uploading it failed: {}", status.message(),
                                                 s.ToString()));
      result->status = status;
      return status;
    }
    status = SkinOnce(request, options.output, part, result);
  }
  return status;
}

Status SkinClient::SkinOnce(const v1::SkinRequest& request, const RegionOutput& output,
                            RawPart* part, FrameResult* result) {
  grpc::ClientContext context;
  SetDeadline(&context, limits_.deadline);
  auto reader = SkinRaw(&context, request);
  FrameAssembler assembler(&output);
  bool complete = false;
  grpc::ByteBuffer bytes;
  while (reader->Read(&bytes)) {
    if (!complete) complete = assembler.Add(bytes, part, result);
  }
  grpc::Status status = reader->Finish();
  if (!status.ok()) {
    result->status = wire::FromGrpc(status);
    result->positions.clear();
    result->normals.clear();
    result->tangents.clear();
    return result->status;
  }
  if (!complete) return Internal("the server ended the frame without its last part");
  return result->status;
}

}  // namespace skinserve::client
