#include "rpc/mesh_assembly.h"

#include "skinserve/wire/conversions.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstring>

namespace skinserve::server {

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
  const Result<RestEncoding> rest_encoding = wire::FromWire(header.rest_encoding());
  if (!rest_encoding.ok()) return rest_encoding.status();
  const std::span<const uint32_t> morph_sizes(header.morph_target_sizes().data(),
                                              header.morph_target_sizes().size());
  if (Status s =
          engine_->CheckMeshShape(header.vertex_count(), header.influences(), header.joint_count(),
                                  header.has_normals(), morph_sizes, header.morph_normals(),
                                  *rest_encoding, header.has_tangents(), header.morph_tangents());
      !s.ok()) {
    return s;
  }
  have_header_ = true;
  normalize_weights_ = header.weight_policy() == v1::WEIGHT_POLICY_NORMALIZE;
  rest_encoding_ = *rest_encoding;
  const uint64_t v = header.vertex_count(), b = header.influences();
  arrays_.vertex_count = header.vertex_count();
  arrays_.influences = header.influences();
  arrays_.joint_count = header.joint_count();
  // Only the sizes are noted: the arrays grow as their chunks arrive (see the header).
  declared_[v1::MESH_ARRAY_POSITIONS] = 3 * v;
  declared_[v1::MESH_ARRAY_NORMALS] = header.has_normals() ? 3 * v : 0;
  declared_[v1::MESH_ARRAY_TANGENTS] = header.has_tangents() ? 4 * v : 0;
  declared_[v1::MESH_ARRAY_JOINTS] = b * v;
  declared_[v1::MESH_ARRAY_WEIGHTS] = b * v;
  // The sizes themselves are at most max_morph_targets numbers (checked above).
  arrays_.morph_target_sizes.assign(morph_sizes.begin(), morph_sizes.end());
  uint64_t deltas = 0;
  for (uint32_t size : morph_sizes) deltas += size;
  declared_[v1::MESH_ARRAY_MORPH_INDICES] = deltas;
  declared_[v1::MESH_ARRAY_MORPH_POSITION_DELTAS] = 3 * deltas;
  declared_[v1::MESH_ARRAY_MORPH_NORMAL_DELTAS] = header.morph_normals() ? 3 * deltas : 0;
  declared_[v1::MESH_ARRAY_MORPH_TANGENT_DELTAS] = header.morph_tangents() ? 3 * deltas : 0;
  ++progress_;
  return Status::Ok();
}

Status MeshAssembly::AcceptChunk(const v1::MeshChunk& chunk) {
  if (!have_header_) return InvalidArgument("chunk before header; the header comes first");
  switch (chunk.array()) {
    case v1::MESH_ARRAY_POSITIONS:
      return Append(arrays_.positions, "positions", chunk);
    case v1::MESH_ARRAY_NORMALS:
      if (declared_[v1::MESH_ARRAY_NORMALS] == 0) {
        return InvalidArgument("normals chunk, but the header says has_normals = false");
      }
      return Append(arrays_.normals, "normals", chunk);
    case v1::MESH_ARRAY_JOINTS:
      return Append(arrays_.joints, "joints", chunk);
    case v1::MESH_ARRAY_WEIGHTS:
      return Append(arrays_.weights, "weights", chunk);
    case v1::MESH_ARRAY_MORPH_INDICES:
      return Append(arrays_.morph_indices, "morph_indices", chunk);
    case v1::MESH_ARRAY_MORPH_POSITION_DELTAS:
      return Append(arrays_.morph_position_deltas, "morph_position_deltas", chunk);
    case v1::MESH_ARRAY_MORPH_NORMAL_DELTAS:
      if (declared_[v1::MESH_ARRAY_MORPH_NORMAL_DELTAS] == 0) {
        return InvalidArgument(
            "morph_normal_deltas chunk, but the header says morph_normals = false (or has no "
            "morph targets)");
      }
      return Append(arrays_.morph_normal_deltas, "morph_normal_deltas", chunk);
    case v1::MESH_ARRAY_TANGENTS:
      if (declared_[v1::MESH_ARRAY_TANGENTS] == 0) {
        return InvalidArgument("tangents chunk, but the header says has_tangents = false");
      }
      return Append(arrays_.tangents, "tangents", chunk);
    case v1::MESH_ARRAY_MORPH_TANGENT_DELTAS:
      if (declared_[v1::MESH_ARRAY_MORPH_TANGENT_DELTAS] == 0) {
        return InvalidArgument(
            "morph_tangent_deltas chunk, but the header says morph_tangents = false (or has no "
            "morph targets)");
      }
      return Append(arrays_.morph_tangent_deltas, "morph_tangent_deltas", chunk);
    default:
      return InvalidArgument(fmt::format("chunk.array {} is not a mesh array", chunk.array()));
  }
}

template <typename T>
Status MeshAssembly::Append(std::vector<T>& array, const char* name, const v1::MeshChunk& chunk) {
  const uint64_t received = array.size(), declared = declared_[chunk.array()];
  if (chunk.offset() != received) {
    return InvalidArgument(
        fmt::format("{} chunk at offset {}; expected offset {} (chunks of an "
                    "array arrive in order)",
                    name, chunk.offset(), received));
  }
  if (chunk.data().size() % sizeof(T) != 0) {
    return InvalidArgument(fmt::format("{} chunk holds {} bytes, not whole {}-byte values", name,
                                       chunk.data().size(), sizeof(T)));
  }
  const uint64_t count = chunk.data().size() / sizeof(T);
  if (received + count > declared) {
    return InvalidArgument(
        fmt::format("{} chunk ends at value {}, past the {} values the header implies", name,
                    received + count, declared));
  }
  if (count == 0) return Status::Ok();  // an array not grown yet has no block to copy into
  if (Status s = Reserve(array, chunk.array(), received + count); !s.ok()) {
    return ResourceExhausted(
        fmt::format("{} chunk at offset {}: {}; nothing was stored", name, received, s.message()));
  }
  array.resize(received + count);  // within the capacity reserved: no allocation
  std::memcpy(array.data() + received, chunk.data().data(), chunk.data().size());
  progress_ += chunk.data().size();
  return Status::Ok();
}

template <typename T>
Status MeshAssembly::Reserve(std::vector<T>& array, int array_number, uint64_t values) {
  if (values <= array.capacity()) return Status::Ok();
  // Doubling keeps the copying linear in the mesh's size; the declared size caps it, so a
  // complete array holds no spare room.
  const uint64_t capacity = std::min<uint64_t>(
      declared_[array_number], std::max<uint64_t>(values, 2 * uint64_t{array.capacity()}));
  const uint64_t bytes = capacity * sizeof(T);
  // The new block is charged in full before it is taken: until the old one is freed
  // below, both are held.
  if (budget_ != nullptr) {
    if (Status s = budget_->TryCharge(bytes); !s.ok()) return s;
  }
  array.reserve(capacity);
  const uint64_t old_bytes = charged_[array_number];
  if (budget_ != nullptr) budget_->Release(old_bytes);
  charged_[array_number] = bytes;
  charged_bytes_ += bytes - old_bytes;
  return Status::Ok();
}

Result<MeshInfo> MeshAssembly::Store() {
  struct DiscardOnReturn {
    MeshAssembly* assembly;
    ~DiscardOnReturn() { assembly->Discard(); }
  } discard{this};
  if (!have_header_) return InvalidArgument("upload ended without a header");
  const std::pair<const char*, std::pair<uint64_t, uint64_t>> arrays[] = {
      {"positions", {arrays_.positions.size(), declared_[v1::MESH_ARRAY_POSITIONS]}},
      {"normals", {arrays_.normals.size(), declared_[v1::MESH_ARRAY_NORMALS]}},
      {"tangents", {arrays_.tangents.size(), declared_[v1::MESH_ARRAY_TANGENTS]}},
      {"joints", {arrays_.joints.size(), declared_[v1::MESH_ARRAY_JOINTS]}},
      {"weights", {arrays_.weights.size(), declared_[v1::MESH_ARRAY_WEIGHTS]}},
      {"morph_indices", {arrays_.morph_indices.size(), declared_[v1::MESH_ARRAY_MORPH_INDICES]}},
      {"morph_position_deltas",
       {arrays_.morph_position_deltas.size(), declared_[v1::MESH_ARRAY_MORPH_POSITION_DELTAS]}},
      {"morph_normal_deltas",
       {arrays_.morph_normal_deltas.size(), declared_[v1::MESH_ARRAY_MORPH_NORMAL_DELTAS]}},
      {"morph_tangent_deltas",
       {arrays_.morph_tangent_deltas.size(), declared_[v1::MESH_ARRAY_MORPH_TANGENT_DELTAS]}}};
  for (const auto& [name, counts] : arrays) {
    if (counts.first != counts.second) {
      return InvalidArgument(
          fmt::format("upload truncated: {} has {} of {} values; nothing was stored", name,
                      counts.first, counts.second));
    }
  }
  // The engine copies the arrays into the mesh store (its own budget); ours are freed
  // right after, so an upload's peak is its arrays plus the stored mesh, once.
  return engine_->AddMesh(arrays_,
                          normalize_weights_ ? WeightPolicy::kNormalize : WeightPolicy::kReject,
                          rest_encoding_);
}

void MeshAssembly::Discard() {
  if (budget_ != nullptr) budget_->Release(charged_bytes_);
  charged_bytes_ = 0;
  std::fill(std::begin(charged_), std::end(charged_), 0);
  std::fill(std::begin(declared_), std::end(declared_), 0);
  arrays_ = MeshArrays();  // frees the blocks, not just their contents
  have_header_ = false;
}

}  // namespace skinserve::server
