#include "skinserve/client/skin_client.h"

#include <fmt/format.h>

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

bool FrameAssembler::Add(const v1::SkinResponse& part, FrameResult* result) {
  result->frame = part.frame();
  if (part.has_error()) {
    result->status = FromGrpc(
        grpc::Status(static_cast<grpc::StatusCode>(part.error().code()), part.error().message()));
    return part.last();
  }
  const std::size_t total = 3ull * part.total_vertices();
  if (result->positions.size() != total) result->positions.resize(total);
  const std::size_t offset = 3ull * part.first_vertex(), count = 3ull * part.vertex_count();
  if (offset + count > total || part.positions().size() != count * sizeof(float) ||
      (!part.normals().empty() && part.normals().size() != count * sizeof(float))) {
    result->status =
        Internal(fmt::format("frame {}: malformed part [{}, +{}) of {} vertices", part.frame(),
                             part.first_vertex(), part.vertex_count(), part.total_vertices()));
    return part.last();
  }
  std::memcpy(result->positions.data() + offset, part.positions().data(), part.positions().size());
  if (!part.normals().empty()) {
    if (result->normals.size() != total) result->normals.resize(total);
    std::memcpy(result->normals.data() + offset, part.normals().data(), part.normals().size());
  }
  received_ += part.vertex_count();
  result->timing = part.timing();
  if (part.last() && received_ != part.total_vertices()) {
    result->status = Internal(fmt::format("frame {}: {} of {} vertices arrived", part.frame(),
                                          received_, part.total_vertices()));
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
  v1::SkinRequest request;
  request.set_mesh_id(mesh_id);
  request.set_backend(backend);
  request.set_frame(frame);
  request.set_palette(EncodePalette(palette));
  request.set_want_normals(want_normals);
  request.set_method(WireMethod(method));
  Status status = SkinOnce(request, result);
  if (status.code() == StatusCode::kNotFound) {
    if (Status s = Reupload(mesh_id); !s.ok()) return status;  // the original NOT_FOUND
    status = SkinOnce(request, result);
  }
  return status;
}

Status SkinClient::SkinOnce(const v1::SkinRequest& request, FrameResult* result) {
  *result = FrameResult();
  grpc::ClientContext context;
  auto reader = stub_->Skin(&context, request);
  v1::SkinResponse part;
  FrameAssembler assembler;
  bool complete = false;
  while (reader->Read(&part)) {
    if (!complete) complete = assembler.Add(part, result);
  }
  grpc::Status status = reader->Finish();
  if (!status.ok()) return FromGrpc(status);
  if (!complete) return Internal("the server ended the frame without its last part");
  return result->status;
}

}  // namespace skinserve::client
