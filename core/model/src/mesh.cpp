#include "skinserve/model/mesh.h"

#include <openssl/evp.h>

#include <fmt/format.h>
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
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  EVP_DigestFinal_ex(ctx, digest, &length);
  EVP_MD_CTX_free(ctx);
  std::string hex;
  hex.reserve(2 * length);
  for (unsigned int i = 0; i < length; ++i) hex += fmt::format("{:02x}", digest[i]);
  return hex;
}

}  // namespace

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

uint64_t MeshByteSize(uint64_t vertex_count, uint64_t influences, bool has_normals) {
  const uint64_t per_vertex =
      3 * sizeof(float) * (has_normals ? 2 : 1) + influences * (sizeof(uint16_t) + sizeof(float));
  return vertex_count * per_vertex;
}

uint64_t Mesh::byte_size() const { return MeshByteSize(vertex_count_, influences_, has_normals()); }

Result<std::shared_ptr<const Mesh>> Mesh::Create(const MeshArrays& arrays,
                                                 const MeshOptions& options) {
  const uint64_t v = arrays.vertex_count;
  const uint64_t b = arrays.influences;
  const uint64_t j = arrays.joint_count;
  if (Status s = CheckMeshHeader(v, b, j, options.limits); !s.ok()) return s;
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
  if (Status s = CheckArraySize("joints", arrays.joints.size(), b * v, "influences * vertex_count");
      !s.ok()) {
    return s;
  }
  if (Status s =
          CheckArraySize("weights", arrays.weights.size(), b * v, "influences * vertex_count");
      !s.ok()) {
    return s;
  }
  if (Status s = CheckFinite3("positions", arrays.positions); !s.ok()) return s;
  if (Status s = CheckFinite3("normals", arrays.normals); !s.ok()) return s;
  for (uint64_t i = 0; i < arrays.normals.size() / 3; ++i) {
    const float* n = &arrays.normals[3 * i];
    if (n[0] == 0.0f && n[1] == 0.0f && n[2] == 0.0f) {
      return InvalidArgument(fmt::format("normals[vertex {}] is the zero vector", i));
    }
  }
  for (uint64_t k = 0; k < arrays.joints.size(); ++k) {
    if (arrays.joints[k] >= j) {
      return InvalidArgument(
          fmt::format("joints[vertex {}, influence {}] = {} is not below joint_count {}", k / b,
                      k % b, arrays.joints[k], j));
    }
  }

  std::shared_ptr<Mesh> mesh(new Mesh());
  mesh->vertex_count_ = static_cast<uint32_t>(v);
  mesh->influences_ = static_cast<uint32_t>(b);
  mesh->joint_count_ = static_cast<uint32_t>(j);
  mesh->weights_ = AlignedBuffer<float>(std::span<const float>(arrays.weights));
  float* weights = mesh->weights_.data();
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
      if (options.weight_policy == WeightPolicy::kReject) {
        return InvalidArgument(fmt::format(
            "weights[vertex {}] sum to {}; they must sum to 1 within {} (or upload with the "
            "normalize weight policy)",
            vertex, sum, kWeightSumTolerance));
      }
      ++mesh->normalized_vertices_;
    }
    // Within tolerance too: an exact sum keeps the blended matrix affine.
    for (uint64_t i = 0; i < b; ++i) w[i] = static_cast<float>(w[i] / sum);
  }
  mesh->positions_ = AlignedBuffer<float>(std::span<const float>(arrays.positions));
  mesh->normals_ = AlignedBuffer<float>(std::span<const float>(arrays.normals));
  mesh->joints_ = AlignedBuffer<uint16_t>(std::span<const uint16_t>(arrays.joints));
  mesh->id_ = ContentId(*mesh);
  return std::shared_ptr<const Mesh>(std::move(mesh));
}

}  // namespace skinserve
