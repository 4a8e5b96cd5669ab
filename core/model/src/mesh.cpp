#include "skinserve/model/mesh.h"

#include <openssl/evp.h>

#include <fmt/format.h>
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>

namespace skinserve {
namespace {

static_assert(std::endian::native == std::endian::little,
              "the canonical mesh bytes (and the wire) are little-endian");

Status CheckArraySize(const char* field, std::size_t actual, uint64_t expected,
                      const char* formula) {
  if (actual == expected) return Status::Ok();
  return InvalidArgument(
      fmt::format("{} holds {} values; expected {} = {}", field, actual, expected, formula));
}

Status CheckFinite3(const char* field, std::span<const float> values) {
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (!std::isfinite(values[i])) {
      return InvalidArgument(fmt::format("{}[vertex {}].{} = {} is not finite", field, i / 3,
                                         "xyz"[i % 3], values[i]));
    }
  }
  return Status::Ok();
}

// Each tangent finite, its xyz of unit length within kTangentLengthTolerance, its w +1 or -1.
Status CheckTangents(std::span<const float> tangents) {
  for (std::size_t v = 0; v < tangents.size() / 4; ++v) {
    const float* t = &tangents[4 * v];
    for (int a = 0; a < 4; ++a) {
      if (!std::isfinite(t[a])) {
        return InvalidArgument(
            fmt::format("tangents[vertex {}].{} = {} is not finite", v, "xyzw"[a], t[a]));
      }
    }
    const double length =
        std::sqrt(double{t[0]} * t[0] + double{t[1]} * t[1] + double{t[2]} * t[2]);
    if (std::fabs(length - 1.0) > kTangentLengthTolerance) {
      return InvalidArgument(fmt::format(
          "tangents[vertex {}].xyz has length {:.6g}; it must be a unit vector within {}", v,
          length, kTangentLengthTolerance));
    }
    if (t[3] != 1.0f && t[3] != -1.0f) {
      return InvalidArgument(fmt::format(
          "tangents[vertex {}].w = {}; it must be exactly +1 or -1 (the handedness)", v, t[3]));
    }
  }
  return Status::Ok();
}

// SHA-256 over a fixed header and the arrays' little-endian bytes, as lowercase hex.
std::string ContentId(const Mesh& mesh) {
  EVP_MD_CTX* ctx = EVP_MD_CTX_new();
  EVP_DigestInit_ex(ctx, EVP_sha256(), nullptr);
  const char kTag[] = "skinserve-mesh-v1";
  EVP_DigestUpdate(ctx, kTag, sizeof(kTag));
  const uint32_t header[4] = {mesh.vertex_count(), mesh.influences(), mesh.joint_count(),
                              mesh.has_normals() ? 1u : 0u};
  EVP_DigestUpdate(ctx, header, sizeof(header));
  auto add = [ctx](auto span) { EVP_DigestUpdate(ctx, span.data(), span.size_bytes()); };
  add(mesh.positions());
  add(mesh.normals());
  add(mesh.joints());
  add(mesh.weights());
  if (mesh.has_tangents()) {  // meshes without tangents keep their ids
    const char kTangentTag[] = "tangents";
    EVP_DigestUpdate(ctx, kTangentTag, sizeof(kTangentTag));
    add(mesh.tangents());
  }
  if (mesh.rest_encoding() != RestEncoding::kFloat32) {  // float meshes keep their ids
    const uint32_t encoding = static_cast<uint32_t>(mesh.rest_encoding());
    EVP_DigestUpdate(ctx, &encoding, sizeof(encoding));
  }
  if (mesh.morph_target_count() > 0) {  // meshes without targets keep their ids
    const uint32_t morph_header[2] = {mesh.morph_target_count(),
                                      mesh.has_morph_normals() ? 1u : 0u};
    EVP_DigestUpdate(ctx, morph_header, sizeof(morph_header));
    add(mesh.morph_offsets());
    add(mesh.morph_indices());
    add(mesh.morph_position_deltas());
    add(mesh.morph_normal_deltas());
    if (mesh.has_morph_tangents()) {
      const char kTangentTag[] = "morph_tangent_deltas";
      EVP_DigestUpdate(ctx, kTangentTag, sizeof(kTangentTag));
      add(mesh.morph_tangent_deltas());
    }
  }
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  EVP_DigestFinal_ex(ctx, digest, &length);
  EVP_MD_CTX_free(ctx);
  std::string hex;
  hex.reserve(2 * length);
  for (unsigned int i = 0; i < length; ++i) hex += fmt::format("{:02x}", digest[i]);
  return hex;
}

// The morph arrays' sizes against the sum of the targets' sizes, `deltas`.
Status CheckMorphArraySizes(const MeshArrays& arrays, uint64_t deltas) {
  if (Status s = CheckArraySize("morph_indices", arrays.morph_indices.size(), deltas,
                                "the sum of morph_target_sizes");
      !s.ok()) {
    return s;
  }
  if (Status s = CheckArraySize("morph_position_deltas", arrays.morph_position_deltas.size(),
                                3 * deltas, "3 * the sum of morph_target_sizes");
      !s.ok()) {
    return s;
  }
  if (!arrays.morph_normal_deltas.empty()) {
    if (Status s = CheckArraySize("morph_normal_deltas", arrays.morph_normal_deltas.size(),
                                  3 * deltas, "3 * the sum of morph_target_sizes (or none)");
        !s.ok()) {
      return s;
    }
  }
  if (!arrays.morph_tangent_deltas.empty()) {
    if (Status s = CheckArraySize("morph_tangent_deltas", arrays.morph_tangent_deltas.size(),
                                  3 * deltas, "3 * the sum of morph_target_sizes (or none)");
        !s.ok()) {
      return s;
    }
  }
  return Status::Ok();
}

// Position deltas are bounded relative to the mesh: beyond kMorphDeltaRange times its
// extent a delta is an exporter's error, not a shape.
double MorphPositionLimit(std::span<const float> positions) {
  float lo[3] = {positions[0], positions[1], positions[2]};
  float hi[3] = {lo[0], lo[1], lo[2]};
  for (std::size_t i = 0; i < positions.size(); ++i) {
    lo[i % 3] = std::min(lo[i % 3], positions[i]);
    hi[i % 3] = std::max(hi[i % 3], positions[i]);
  }
  double diagonal = 0;
  for (int a = 0; a < 3; ++a) diagonal += (double{hi[a]} - lo[a]) * (double{hi[a]} - lo[a]);
  return kMorphDeltaRange * std::max(1.0, std::sqrt(diagonal));
}

// Target t's deltas, [first, last) of the morph arrays: vertices in range and ascending,
// deltas finite and within their limits.
Status CheckMorphTarget(const MeshArrays& arrays, std::size_t t, uint64_t first, uint64_t last,
                        double position_limit) {
  for (uint64_t k = first; k < last; ++k) {
    const uint32_t vertex = arrays.morph_indices[k];
    if (vertex >= arrays.vertex_count) {
      return InvalidArgument(
          fmt::format("morph_indices[target {}, delta {}] = {} is not below vertex_count {}", t,
                      k - first, vertex, arrays.vertex_count));
    }
    if (k > first && vertex <= arrays.morph_indices[k - 1]) {
      return InvalidArgument(fmt::format(
          "morph_indices[target {}, delta {}] = {} does not ascend (the one before is {}); "
          "each target lists its vertices once, in ascending order",
          t, k - first, vertex, arrays.morph_indices[k - 1]));
    }
    for (int a = 0; a < 3; ++a) {
      const float d = arrays.morph_position_deltas[3 * k + a];
      if (!std::isfinite(d) || std::fabs(d) > position_limit) {
        return InvalidArgument(fmt::format(
            "morph_position_deltas[target {}, delta {}].{} = {} must be finite and within "
            "+-{:g} ({} times the mesh's extent, at least 1)",
            t, k - first, "xyz"[a], d, position_limit, kMorphDeltaRange));
      }
      if (arrays.morph_normal_deltas.empty()) continue;
      const float n = arrays.morph_normal_deltas[3 * k + a];
      if (!std::isfinite(n) || std::fabs(n) > kMaxMorphNormalDelta) {
        return InvalidArgument(
            fmt::format("morph_normal_deltas[target {}, delta {}].{} = {} must be finite and "
                        "within +-{}",
                        t, k - first, "xyz"[a], n, kMaxMorphNormalDelta));
      }
    }
    for (int a = 0; a < 3 && !arrays.morph_tangent_deltas.empty(); ++a) {
      const float d = arrays.morph_tangent_deltas[3 * k + a];
      if (!std::isfinite(d) || std::fabs(d) > kMaxMorphNormalDelta) {
        return InvalidArgument(
            fmt::format("morph_tangent_deltas[target {}, delta {}].{} = {} must be finite and "
                        "within +-{}",
                        t, k - first, "xyz"[a], d, kMaxMorphNormalDelta));
      }
    }
  }
  return Status::Ok();
}

// Validates the morph arrays of `arrays` (their header already checked by CheckMorphHeader).
Status CheckMorphArrays(const MeshArrays& arrays, uint64_t deltas) {
  if (Status s = CheckMorphArraySizes(arrays, deltas); !s.ok()) return s;
  const double position_limit = MorphPositionLimit(arrays.positions);
  uint64_t first = 0;
  for (std::size_t t = 0; t < arrays.morph_target_sizes.size(); ++t) {
    const uint64_t last = first + arrays.morph_target_sizes[t];
    if (Status s = CheckMorphTarget(arrays, t, first, last, position_limit); !s.ok()) return s;
    first = last;
  }
  return Status::Ok();
}

}  // namespace

Status CheckMorphHeader(std::span<const uint32_t> target_sizes, uint64_t vertex_count,
                        bool has_normals, bool morph_normals, const MeshLimits& limits,
                        bool has_tangents, bool morph_tangents) {
  const uint32_t max_targets = std::min(limits.max_morph_targets, kMaxMorphTargets);
  if (target_sizes.size() > max_targets) {
    return ResourceExhausted(
        fmt::format("morph_target_sizes lists {} targets, over the limit of {} targets per mesh",
                    target_sizes.size(), max_targets));
  }
  if (morph_normals && target_sizes.empty()) {
    return InvalidArgument("morph normal deltas were declared but the mesh has no morph targets");
  }
  if (morph_normals && !has_normals) {
    return InvalidArgument("morph normal deltas were declared but the mesh has no normals");
  }
  if (morph_tangents && target_sizes.empty()) {
    return InvalidArgument("morph tangent deltas were declared but the mesh has no morph targets");
  }
  if (morph_tangents && !has_tangents) {
    return InvalidArgument("morph tangent deltas were declared but the mesh has no tangents");
  }
  uint64_t deltas = 0;
  for (std::size_t t = 0; t < target_sizes.size(); ++t) {
    if (target_sizes[t] > vertex_count) {
      return InvalidArgument(
          fmt::format("morph_target_sizes[{}] = {} exceeds vertex_count {}; a target moves each "
                      "vertex at most once",
                      t, target_sizes[t], vertex_count));
    }
    deltas += target_sizes[t];
  }
  // Offsets are 32-bit: no limit reaches past them.
  const uint64_t max_deltas = std::min<uint64_t>(limits.max_morph_deltas, UINT32_MAX);
  if (deltas > max_deltas) {
    return ResourceExhausted(
        fmt::format("morph targets hold {} deltas in all, over the limit of {} deltas per mesh",
                    deltas, max_deltas));
  }
  return Status::Ok();
}

Status CheckMeshHeader(uint64_t vertex_count, uint64_t influences, uint64_t joint_count,
                       const MeshLimits& limits) {
  if (vertex_count == 0) return InvalidArgument("vertex_count is 0; a mesh needs at least 1");
  if (vertex_count > limits.max_vertices) {
    return ResourceExhausted(fmt::format("vertex_count {} exceeds the limit of {} vertices",
                                         vertex_count, limits.max_vertices));
  }
  if (influences < 1 || influences > kMaxInfluences) {
    return InvalidArgument(
        fmt::format("influences is {}; it must be 1..{}", influences, kMaxInfluences));
  }
  if (joint_count == 0) return InvalidArgument("joint_count is 0; a mesh needs at least 1");
  if (joint_count > kMaxJointsLimit) {
    return InvalidArgument(fmt::format("joint_count {} exceeds {}, the most a uint16 index reaches",
                                       joint_count, kMaxJointsLimit));
  }
  if (joint_count > limits.max_joints) {
    return ResourceExhausted(fmt::format("joint_count {} exceeds the limit of {} joints",
                                         joint_count, limits.max_joints));
  }
  return Status::Ok();
}

Status CheckRestEncoding(RestEncoding encoding, uint64_t morph_targets) {
  if (encoding != RestEncoding::kFloat32 && morph_targets > 0) {
    return InvalidArgument(fmt::format(
        "rest_encoding {} with {} morph targets: a quantized rest stream carries no morph "
        "targets (their deltas add to the float rest arrays); upload it as float32",
        RestEncodingName(encoding), morph_targets));
  }
  return Status::Ok();
}

uint64_t MeshByteSize(uint64_t vertex_count, uint64_t influences, bool has_normals,
                      uint64_t morph_targets, uint64_t morph_deltas, bool morph_normals,
                      RestEncoding rest_encoding, uint64_t joint_count, bool has_tangents,
                      bool morph_tangents) {
  const uint64_t per_vertex = 3 * sizeof(float) * (has_normals ? 2 : 1) +
                              (has_tangents ? 4 * sizeof(float) : 0) +
                              influences * (sizeof(uint16_t) + sizeof(float));
  const uint64_t per_delta = sizeof(uint32_t) + 3 * sizeof(float) * (morph_normals ? 2 : 1) +
                             (morph_tangents ? 3 * sizeof(float) : 0);
  const uint64_t offsets = morph_targets > 0 ? (morph_targets + 1) * sizeof(uint32_t) : 0;
  const uint64_t quantized = QuantizedRestBytesPerVertex(rest_encoding, influences, joint_count,
                                                         has_normals, has_tangents);
  return vertex_count * (per_vertex + quantized) + morph_deltas * per_delta + offsets;
}

uint64_t Mesh::byte_size() const {
  return MeshByteSize(vertex_count_, influences_, has_normals(), morph_target_count_,
                      morph_indices_.size(), has_morph_normals(), rest_encoding(), joint_count_,
                      has_tangents(), has_morph_tangents());
}

namespace {

// The vertex arrays' sizes against vertex_count and influences (tangents need normals).
Status CheckVertexArraySizes(const MeshArrays& arrays) {
  const uint64_t v = arrays.vertex_count;
  const uint64_t b = arrays.influences;
  if (Status s = CheckArraySize("positions", arrays.positions.size(), 3 * v, "3 * vertex_count");
      !s.ok()) {
    return s;
  }
  if (!arrays.normals.empty()) {
    if (Status s =
            CheckArraySize("normals", arrays.normals.size(), 3 * v, "3 * vertex_count (or none)");
        !s.ok()) {
      return s;
    }
  }
  if (!arrays.tangents.empty()) {
    if (arrays.normals.empty()) {
      return InvalidArgument(
          "tangents were given but normals were not; tangents need normals (as in glTF)");
    }
    if (Status s =
            CheckArraySize("tangents", arrays.tangents.size(), 4 * v, "4 * vertex_count (or none)");
        !s.ok()) {
      return s;
    }
  }
  if (Status s = CheckArraySize("joints", arrays.joints.size(), b * v, "influences * vertex_count");
      !s.ok()) {
    return s;
  }
  if (Status s =
          CheckArraySize("weights", arrays.weights.size(), b * v, "influences * vertex_count");
      !s.ok()) {
    return s;
  }
  return Status::Ok();
}

// The vertex arrays' values: finite positions and normals, no zero normal, unit tangents,
// joints below joint_count.
Status CheckVertexValues(const MeshArrays& arrays) {
  const uint64_t b = arrays.influences;
  const uint64_t j = arrays.joint_count;
  if (Status s = CheckFinite3("positions", arrays.positions); !s.ok()) return s;
  if (Status s = CheckFinite3("normals", arrays.normals); !s.ok()) return s;
  for (uint64_t i = 0; i < arrays.normals.size() / 3; ++i) {
    const float* n = &arrays.normals[3 * i];
    if (n[0] == 0.0f && n[1] == 0.0f && n[2] == 0.0f) {
      return InvalidArgument(fmt::format("normals[vertex {}] is the zero vector", i));
    }
  }
  if (Status s = CheckTangents(arrays.tangents); !s.ok()) return s;
  for (uint64_t k = 0; k < arrays.joints.size(); ++k) {
    if (arrays.joints[k] >= j) {
      return InvalidArgument(
          fmt::format("joints[vertex {}, influence {}] = {} is not below joint_count {}", k / b,
                      k % b, arrays.joints[k], j));
    }
  }
  return Status::Ok();
}

// Each vertex's `b` weights finite, >= 0 and not all zero, then divided by their sum; a sum
// farther than kWeightSumTolerance from 1 is refused under WeightPolicy::kReject, else
// counted in `normalized`.
Status NormalizeWeights(float* weights, uint64_t v, uint64_t b, WeightPolicy policy,
                        uint32_t* normalized) {
  for (uint64_t vertex = 0; vertex < v; ++vertex) {
    float* w = weights + vertex * b;
    double sum = 0;
    for (uint64_t i = 0; i < b; ++i) {
      if (!std::isfinite(w[i]) || w[i] < 0.0f) {
        return InvalidArgument(
            fmt::format("weights[vertex {}, influence {}] = {}; weights must be finite and >= 0",
                        vertex, i, w[i]));
      }
      sum += w[i];
    }
    if (sum <= 0) {
      return InvalidArgument(
          fmt::format("weights[vertex {}] are all zero; each vertex needs a weight > 0", vertex));
    }
    if (std::abs(sum - 1.0) > kWeightSumTolerance) {
      if (policy == WeightPolicy::kReject) {
        return InvalidArgument(fmt::format(
            "weights[vertex {}] sum to {}; they must sum to 1 within {} (or upload with the "
            "normalize weight policy)",
            vertex, sum, kWeightSumTolerance));
      }
      ++*normalized;
    }
    // Within tolerance too: an exact sum keeps the blended matrix affine.
    for (uint64_t i = 0; i < b; ++i) w[i] = static_cast<float>(w[i] / sum);
  }
  return Status::Ok();
}

}  // namespace

Result<std::shared_ptr<const Mesh>> Mesh::Create(const MeshArrays& arrays,
                                                 const MeshOptions& options) {
  const uint64_t v = arrays.vertex_count;
  const uint64_t b = arrays.influences;
  const uint64_t j = arrays.joint_count;
  if (Status s = CheckMeshHeader(v, b, j, options.limits); !s.ok()) return s;
  if (Status s = CheckVertexArraySizes(arrays); !s.ok()) return s;
  if (Status s = CheckMorphHeader(arrays.morph_target_sizes, v, !arrays.normals.empty(),
                                  !arrays.morph_normal_deltas.empty(), options.limits,
                                  !arrays.tangents.empty(), !arrays.morph_tangent_deltas.empty());
      !s.ok()) {
    return s;
  }
  if (Status s = CheckVertexValues(arrays); !s.ok()) return s;
  if (Status s = CheckRestEncoding(options.rest_encoding, arrays.morph_target_sizes.size());
      !s.ok()) {
    return s;
  }
  uint64_t deltas = 0;
  for (uint32_t size : arrays.morph_target_sizes) deltas += size;
  if (Status s = CheckMorphArrays(arrays, deltas); !s.ok()) return s;

  std::shared_ptr<Mesh> mesh(new Mesh());
  mesh->vertex_count_ = static_cast<uint32_t>(v);
  mesh->influences_ = static_cast<uint32_t>(b);
  mesh->joint_count_ = static_cast<uint32_t>(j);
  mesh->weights_ = AlignedBuffer<float>(std::span<const float>(arrays.weights));
  if (Status s = NormalizeWeights(mesh->weights_.data(), v, b, options.weight_policy,
                                  &mesh->normalized_vertices_);
      !s.ok()) {
    return s;
  }
  mesh->positions_ = AlignedBuffer<float>(std::span<const float>(arrays.positions));
  mesh->normals_ = AlignedBuffer<float>(std::span<const float>(arrays.normals));
  mesh->tangents_ = AlignedBuffer<float>(std::span<const float>(arrays.tangents));
  mesh->joints_ = AlignedBuffer<uint16_t>(std::span<const uint16_t>(arrays.joints));
  if (!arrays.morph_target_sizes.empty()) {
    mesh->morph_target_count_ = static_cast<uint32_t>(arrays.morph_target_sizes.size());
    mesh->morph_offsets_ = AlignedBuffer<uint32_t>(arrays.morph_target_sizes.size() + 1);
    uint32_t offset = 0;
    for (std::size_t t = 0; t < arrays.morph_target_sizes.size(); ++t) {
      mesh->morph_offsets_[t] = offset;
      offset += arrays.morph_target_sizes[t];
    }
    mesh->morph_offsets_[arrays.morph_target_sizes.size()] = offset;
    mesh->morph_indices_ = AlignedBuffer<uint32_t>(std::span<const uint32_t>(arrays.morph_indices));
    mesh->morph_position_deltas_ =
        AlignedBuffer<float>(std::span<const float>(arrays.morph_position_deltas));
    mesh->morph_normal_deltas_ =
        AlignedBuffer<float>(std::span<const float>(arrays.morph_normal_deltas));
    mesh->morph_tangent_deltas_ =
        AlignedBuffer<float>(std::span<const float>(arrays.morph_tangent_deltas));
  }
  if (options.rest_encoding != RestEncoding::kFloat32) {
    mesh->quantized_ =
        Quantize(options.rest_encoding, mesh->vertex_count_, mesh->influences_, mesh->joint_count_,
                 mesh->positions_.span(), mesh->normals_.span(), mesh->tangents_.span(),
                 mesh->joints_.span(), mesh->weights_.span());
  }
  mesh->id_ = ContentId(*mesh);
  return std::shared_ptr<const Mesh>(std::move(mesh));
}

}  // namespace skinserve
