#include "mesh_assembly.h"

#include <fmt/format.h>

#include <cstring>
#include <utility>

namespace skinserve::server {
namespace {

// Where a chunk's values go, and how many the header promised.
struct Target {
  const char* name;
  void* data;
  std::size_t value_size;
  uint64_t expected;
};

}  // namespace

Status MeshAssembly::Accept(const v1::UploadMeshRequest& message) {
  switch (message.part_case()) {
    case v1::UploadMeshRequest::kHeader:
      return AcceptHeader(message.header());
    case v1::UploadMeshRequest::kChunk:
      return AcceptChunk(message.chunk());
    default:
      return InvalidArgument("an UploadMeshRequest carries neither header nor chunk");
  }
}

Status MeshAssembly::AcceptHeader(const v1::MeshHeader& header) {
  if (have_header_) return InvalidArgument("header sent twice; send it once, first");
  if (Status s = engine_->CheckMeshShape(header.vertex_count(), header.influences(),
                                         header.joint_count(), header.has_normals());
      !s.ok()) {
    return s;
  }
  have_header_ = true;
  normalize_weights_ = header.weight_policy() == v1::WEIGHT_POLICY_NORMALIZE;
  const uint64_t v = header.vertex_count(), b = header.influences();
  arrays_.vertex_count = header.vertex_count();
  arrays_.influences = header.influences();
  arrays_.joint_count = header.joint_count();
  arrays_.positions.resize(3 * v);
  arrays_.normals.resize(header.has_normals() ? 3 * v : 0);
  arrays_.joints.resize(b * v);
  arrays_.weights.resize(b * v);
  return Status::Ok();
}

Status MeshAssembly::AcceptChunk(const v1::MeshChunk& chunk) {
  if (!have_header_) return InvalidArgument("chunk before header; the header comes first");
  Target target;
  switch (chunk.array()) {
    case v1::MESH_ARRAY_POSITIONS:
      target = {"positions", arrays_.positions.data(), sizeof(float), arrays_.positions.size()};
      break;
    case v1::MESH_ARRAY_NORMALS:
      if (arrays_.normals.empty()) {
        return InvalidArgument("normals chunk, but the header says has_normals = false");
      }
      target = {"normals", arrays_.normals.data(), sizeof(float), arrays_.normals.size()};
      break;
    case v1::MESH_ARRAY_JOINTS:
      target = {"joints", arrays_.joints.data(), sizeof(uint16_t), arrays_.joints.size()};
      break;
    case v1::MESH_ARRAY_WEIGHTS:
      target = {"weights", arrays_.weights.data(), sizeof(float), arrays_.weights.size()};
      break;
    default:
      return InvalidArgument(fmt::format("chunk.array {} is not a mesh array", chunk.array()));
  }
  uint64_t& received = received_[chunk.array()];
  if (chunk.offset() != received) {
    return InvalidArgument(
        fmt::format("{} chunk at offset {}; expected offset {} (chunks of an "
                    "array arrive in order)",
                    target.name, chunk.offset(), received));
  }
  if (chunk.data().size() % target.value_size != 0) {
    return InvalidArgument(fmt::format("{} chunk holds {} bytes, not whole {}-byte values",
                                       target.name, chunk.data().size(), target.value_size));
  }
  const uint64_t count = chunk.data().size() / target.value_size;
  if (received + count > target.expected) {
    return InvalidArgument(
        fmt::format("{} chunk ends at value {}, past the {} values the header implies", target.name,
                    received + count, target.expected));
  }
  std::memcpy(static_cast<char*>(target.data) + received * target.value_size, chunk.data().data(),
              chunk.data().size());
  received += count;
  return Status::Ok();
}

Result<MeshInfo> MeshAssembly::Store() {
  if (!have_header_) return InvalidArgument("upload ended without a header");
  const std::pair<const char*, std::pair<uint64_t, std::size_t>> arrays[] = {
      {"positions", {received_[v1::MESH_ARRAY_POSITIONS], arrays_.positions.size()}},
      {"normals", {received_[v1::MESH_ARRAY_NORMALS], arrays_.normals.size()}},
      {"joints", {received_[v1::MESH_ARRAY_JOINTS], arrays_.joints.size()}},
      {"weights", {received_[v1::MESH_ARRAY_WEIGHTS], arrays_.weights.size()}}};
  for (const auto& [name, counts] : arrays) {
    if (counts.first != counts.second) {
      return InvalidArgument(
          fmt::format("upload truncated: {} has {} of {} values; nothing was stored", name,
                      counts.first, counts.second));
    }
  }
  return engine_->AddMesh(arrays_,
                          normalize_weights_ ? WeightPolicy::kNormalize : WeightPolicy::kReject);
}

}  // namespace skinserve::server
