#include "skinserve/client/skin_client.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstring>

#include "skinserve/client/channel.h"

namespace skinserve::client {

std::string EncodePalette(std::span<const float> palette) {
  return std::string(reinterpret_cast<const char*>(palette.data()), palette.size_bytes());
}

v1::SkinningMethod WireMethod(SkinningMethod method) {
  return method == SkinningMethod::kDualQuaternion ? v1::SKINNING_METHOD_DUAL_QUATERNION
                                                   : v1::SKINNING_METHOD_LINEAR;
}

void EncodePaletteInto(std::span<const float> palette, std::string* bytes) {
  bytes->resize(palette.size_bytes());
  if (!palette.empty()) std::memcpy(bytes->data(), palette.data(), palette.size_bytes());
}

namespace {

Bounds FromWire(const v1::Bounds& b) {
  return {{b.min_x(), b.min_y(), b.min_z()}, {b.max_x(), b.max_y(), b.max_z()}};
}

}  // namespace

bool FrameAssembler::Fail(const v1::SkinResponse& part, FrameResult* result, Status status) {
  failed_ = true;
  result->status = std::move(status);
  result->positions.clear();  // keeps the capacity for the next frame
  result->normals.clear();
  result->bounds.clear();
  return part.last();
}

bool FrameAssembler::Add(const v1::SkinResponse& part, FrameResult* result) {
  const uint32_t instances = std::max(part.instances(), 1u);  // 0: a server before crowds
  const auto encoding = static_cast<VertexEncoding>(part.encoding());
  if (!started_) {
    started_ = true;
    result->frame = part.frame();
    result->status = Status::Ok();
    result->timing = part.timing();
    if (part.has_error()) {
      return Fail(part, result,
                  FromGrpc(grpc::Status(static_cast<grpc::StatusCode>(part.error().code()),
                                        part.error().message())));
    }
    if (!v1::Encoding_IsValid(part.encoding())) {
      return Fail(part, result,
                  Internal(fmt::format("frame {}: unknown encoding {}", part.frame(),
                                       static_cast<int>(part.encoding()))));
    }
    const uint64_t vertices = uint64_t{instances} * part.total_vertices();
    if (vertices > kMaxFrameVertices) {
      return Fail(
          part, result,
          Internal(fmt::format("frame {}: {} instances x {} vertices is more than the "
                               "client accepts ({})",
                               part.frame(), instances, part.total_vertices(), kMaxFrameVertices)));
    }
    result->vertices = part.total_vertices();
    result->instances = instances;
    result->encoding = encoding;
    normals_ = !part.normals().empty();
    result->positions.resize(3 * vertices);  // same size as last frame: no work
    result->normals.resize(normals_ ? 3 * vertices : 0);
    result->bounds.assign(instances, Bounds{});
  }
  if (failed_) return part.last();
  const auto where = [&] {
    return fmt::format("frame {}, instance {}, vertices [{}, +{})", part.frame(), part.instance(),
                       part.first_vertex(), part.vertex_count());
  };
  if (part.frame() != result->frame || part.has_error() ||
      part.total_vertices() != result->vertices || instances != result->instances ||
      encoding != result->encoding || normals_ == part.normals().empty()) {
    return Fail(part, result,
                Internal(fmt::format("{}: the part does not match its frame's first part "
                                     "(frame {}, {} x {} vertices, {}, normals {})",
                                     where(), result->frame, result->instances, result->vertices,
                                     VertexEncodingName(result->encoding), normals_)));
  }
  // A packed part holds `packed` whole instances; else one instance's vertex range.
  const uint32_t packed = std::max(part.instance_count(), 1u);
  if (part.instance() != next_instance_ || part.first_vertex() != next_vertex_ ||
      part.vertex_count() == 0 ||
      uint64_t{part.first_vertex()} + part.vertex_count() > result->vertices ||
      (packed > 1 && (part.first_vertex() != 0 || part.vertex_count() != result->vertices ||
                      uint64_t{part.instance()} + packed > result->instances))) {
    return Fail(part, result,
                Internal(fmt::format("{}: out of order or out of range: instance {} vertex {} "
                                     "was due, {} vertices per instance, {} instance(s) in the "
                                     "part of {}",
                                     where(), next_instance_, next_vertex_, result->vertices,
                                     packed, result->instances)));
  }
  if (packed > 1 && encoding == VertexEncoding::kSnorm16 &&
      part.instance_bounds_size() != static_cast<int>(packed)) {
    return Fail(part, result,
                Internal(fmt::format("{}: {} instances in the part but {} instance_bounds", where(),
                                     packed, part.instance_bounds_size())));
  }
  const auto bytes = [](const std::string& s) {
    return std::span<const std::byte>(reinterpret_cast<const std::byte*>(s.data()), s.size());
  };
  const std::size_t count = 3ull * part.vertex_count();
  const std::size_t instance_bytes = count * EncodedBytesPerValue(encoding);
  if (packed > 1 && (part.positions().size() != packed * instance_bytes ||
                     (normals_ && part.normals().size() != packed * instance_bytes))) {
    return Fail(part, result,
                Internal(fmt::format("{}: {} and {} bytes of positions and normals for {} "
                                     "instances of {} bytes",
                                     where(), part.positions().size(), part.normals().size(),
                                     packed, instance_bytes)));
  }
  for (uint32_t k = 0; k < packed; ++k) {
    const uint32_t instance = part.instance() + k;
    const Bounds bounds = FromWire(packed > 1 && encoding == VertexEncoding::kSnorm16
                                       ? part.instance_bounds(static_cast<int>(k))
                                       : part.bounds());
    Bounds& instance_bounds = result->bounds[instance];
    if (part.first_vertex() == 0) {
      instance_bounds = bounds;
    } else if (bounds != instance_bounds) {
      return Fail(part, result,
                  Internal(fmt::format("{}: bounds differ from the instance's "
                                       "first part",
                                       where())));
    }
    const std::size_t offset = 3 * (uint64_t{instance} * result->vertices + part.first_vertex());
    const auto slice = [&](const std::string& s) {
      return packed > 1 ? bytes(s).subspan(k * instance_bytes, instance_bytes) : bytes(s);
    };
    Status decoded = DecodePositions(encoding, slice(part.positions()), bounds,
                                     std::span<float>(result->positions).subspan(offset, count));
    if (decoded.ok() && normals_) {
      decoded = DecodeNormals(encoding, slice(part.normals()),
                              std::span<float>(result->normals).subspan(offset, count));
    }
    if (!decoded.ok()) {
      return Fail(part, result, Internal(fmt::format("{}: {}", where(), decoded.message())));
    }
  }
  if (packed > 1) {
    next_instance_ += packed;
    next_vertex_ = 0;
  } else {
    next_vertex_ += part.vertex_count();
    if (next_vertex_ == result->vertices) {
      ++next_instance_;
      next_vertex_ = 0;
    }
  }
  if (part.last() && next_instance_ != result->instances) {
    return Fail(part, result,
                Internal(fmt::format("frame {}: ended at instance {} vertex {} of {} x {} "
                                     "vertices",
                                     part.frame(), next_instance_, next_vertex_, result->instances,
                                     result->vertices)));
  }
  if (!part.last() && next_instance_ == result->instances) {
    return Fail(part, result,
                Internal(fmt::format("{}: the frame is complete but the part is not marked last",
                                     where())));
  }
  return part.last();
}

SkinClient::SkinClient(std::shared_ptr<grpc::Channel> channel)
    : channel_(std::move(channel)), stub_(v1::Skinning::NewStub(channel_)) {}

Result<v1::MeshInfo> SkinClient::Upload(const MeshArrays& arrays, WeightPolicy weight_policy) {
  // Validate and hash locally: the id tells whether the server already has this content.
  auto mesh =
      Mesh::Create(arrays, {.limits = {.max_vertices = UINT32_MAX, .max_joints = kMaxJointsLimit},
                            .weight_policy = weight_policy});
  if (!mesh.ok()) return mesh.status();
  {
    std::lock_guard lock(mutex_);
    uploaded_[(*mesh)->id()] = {std::make_shared<MeshArrays>(arrays), weight_policy};
  }
  auto existing = GetMesh((*mesh)->id());
  if (existing.ok()) return existing;
  if (existing.status().code() != StatusCode::kNotFound) return existing.status();
  return SendUpload(arrays, weight_policy);
}

void SkinClient::Remember(const std::string& mesh_id, std::shared_ptr<const MeshArrays> arrays,
                          WeightPolicy weight_policy) {
  std::lock_guard lock(mutex_);
  uploaded_[mesh_id] = {std::move(arrays), weight_policy};
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
  auto info = SendUpload(*uploaded.arrays, uploaded.weight_policy);
  return info.status();
}

Result<v1::MeshInfo> SkinClient::SendUpload(const MeshArrays& arrays, WeightPolicy weight_policy) {
  grpc::ClientContext context;
  v1::MeshInfo info;
  auto writer = stub_->UploadMesh(&context, &info);
  v1::UploadMeshRequest request;
  v1::MeshHeader* header = request.mutable_header();
  header->set_vertex_count(arrays.vertex_count);
  header->set_influences(arrays.influences);
  header->set_joint_count(arrays.joint_count);
  header->set_has_normals(!arrays.normals.empty());
  header->set_weight_policy(weight_policy == WeightPolicy::kNormalize ? v1::WEIGHT_POLICY_NORMALIZE
                                                                      : v1::WEIGHT_POLICY_REJECT);
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
  if (sending) writer->WritesDone();
  grpc::Status status = writer->Finish();
  if (!status.ok()) return FromGrpc(status);
  return info;
}

Result<v1::MeshInfo> SkinClient::GetMesh(const std::string& mesh_id) {
  grpc::ClientContext context;
  v1::GetMeshRequest request;
  request.set_mesh_id(mesh_id);
  v1::MeshInfo info;
  grpc::Status status = stub_->GetMesh(&context, request, &info);
  if (!status.ok()) return FromGrpc(status);
  return info;
}

Result<bool> SkinClient::DeleteMesh(const std::string& mesh_id) {
  grpc::ClientContext context;
  v1::DeleteMeshRequest request;
  request.set_mesh_id(mesh_id);
  v1::DeleteMeshResponse response;
  grpc::Status status = stub_->DeleteMesh(&context, request, &response);
  if (!status.ok()) return FromGrpc(status);
  return response.deleted();
}

Result<v1::ListBackendsResponse> SkinClient::ListBackends() {
  grpc::ClientContext context;
  v1::ListBackendsResponse response;
  grpc::Status status = stub_->ListBackends(&context, v1::ListBackendsRequest(), &response);
  if (!status.ok()) return FromGrpc(status);
  return response;
}

Result<v1::ServerStats> SkinClient::GetServerStats() {
  grpc::ClientContext context;
  v1::ServerStats response;
  grpc::Status status = stub_->GetServerStats(&context, v1::GetServerStatsRequest(), &response);
  if (!status.ok()) return FromGrpc(status);
  return response;
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
  v1::SkinResponse own_part;
  v1::SkinRequest& request = lock.owns_lock() ? skin_request_ : own_request;
  v1::SkinResponse* part = lock.owns_lock() ? &skin_part_ : &own_part;
  request.set_mesh_id(mesh_id);
  request.set_backend(options.backend);
  request.set_frame(frame);
  EncodePaletteInto(palette, request.mutable_palette());
  request.set_want_normals(options.want_normals);
  request.set_method(WireMethod(options.method));
  request.set_encoding(static_cast<v1::Encoding>(options.encoding));
  request.set_instances(options.instances);
  request.set_pack_instances(true);  // FrameAssembler takes packed parts
  Status status = SkinOnce(request, part, result);
  if (status.code() == StatusCode::kNotFound) {
    if (Status s = Reupload(mesh_id); !s.ok()) return status;  // the original NOT_FOUND
    status = SkinOnce(request, part, result);
  }
  return status;
}

Status SkinClient::SkinOnce(const v1::SkinRequest& request, v1::SkinResponse* part,
                            FrameResult* result) {
  grpc::ClientContext context;
  auto reader = stub_->Skin(&context, request);
  FrameAssembler assembler;
  bool complete = false;
  while (reader->Read(part)) {
    if (!complete) complete = assembler.Add(*part, result);
  }
  grpc::Status status = reader->Finish();
  if (!status.ok()) {
    result->status = FromGrpc(status);
    result->positions.clear();
    result->normals.clear();
    return result->status;
  }
  if (!complete) return Internal("the server ended the frame without its last part");
  return result->status;
}

}  // namespace skinserve::client
