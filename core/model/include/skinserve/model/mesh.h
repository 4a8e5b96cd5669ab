// Mesh: a skinned mesh, validated on ingest and immutable afterwards.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "skinserve/model/aligned_buffer.h"
#include "skinserve/model/status.h"

namespace skinserve {

inline constexpr uint32_t kMaxInfluences = 8;       // B: influences per vertex, 1..8
inline constexpr uint32_t kMaxJointsLimit = 65535;  // joint indices are uint16
inline constexpr float kWeightSumTolerance = 1e-3f;

// Limits an operator sets; checked before anything is allocated.
struct MeshLimits {
  uint32_t max_vertices = 4'000'000;
  uint32_t max_joints = 1024;
};

// What to do with a vertex whose weights do not sum to 1 within kWeightSumTolerance.
enum class WeightPolicy {
  kReject,     // INVALID_ARGUMENT naming the vertex (the default)
  kNormalize,  // divide by the sum and count it in Mesh::normalized_vertices()
};

struct MeshOptions {
  MeshLimits limits;
  WeightPolicy weight_policy = WeightPolicy::kReject;
};

// A mesh as plain arrays, before validation. Field names match the wire contract.
//  - positions: 3 * vertex_count floats, x y z per vertex, finite.
//  - normals:   empty, or 3 * vertex_count finite floats (renormalised after skinning).
//  - joints:    influences * vertex_count indices, vertex-major (joints[v * B + i]), each
//               < joint_count. Unused influences are padding: weight 0, any valid index.
//  - weights:   influences * vertex_count floats, vertex-major, each >= 0, summing to 1
//               per vertex within kWeightSumTolerance (within it they are renormalised to
//               sum exactly 1; beyond it see WeightPolicy).
struct MeshArrays {
  uint32_t vertex_count = 0;
  uint32_t influences = 0;
  uint32_t joint_count = 0;
  std::vector<float> positions;
  std::vector<float> normals;
  std::vector<uint16_t> joints;
  std::vector<float> weights;
};

// Checks the sizes a mesh declares before its arrays arrive (an upload's header).
Status CheckMeshHeader(uint64_t vertex_count, uint64_t influences, uint64_t joint_count,
                       const MeshLimits& limits);

// Bytes a mesh of this shape occupies once stored.
uint64_t MeshByteSize(uint64_t vertex_count, uint64_t influences, bool has_normals);

class Mesh {
 public:
  // Validates `arrays` and copies them into aligned storage. Every error names the
  // field, the index and the limit, e.g. "joints[vertex 12, influence 2] = 80 is not
  // below joint_count 77".
  static Result<std::shared_ptr<const Mesh>> Create(const MeshArrays& arrays,
                                                    const MeshOptions& options = {});

  // Content hash of the canonical mesh bytes (SHA-256, lowercase hex): equal meshes
  // have equal ids on every replica and across restarts.
  const std::string& id() const { return id_; }
  uint32_t vertex_count() const { return vertex_count_; }
  uint32_t influences() const { return influences_; }
  uint32_t joint_count() const { return joint_count_; }
  bool has_normals() const { return !normals_.empty(); }
  std::span<const float> positions() const { return positions_.span(); }
  std::span<const float> normals() const { return normals_.span(); }
  std::span<const uint16_t> joints() const { return joints_.span(); }
  std::span<const float> weights() const { return weights_.span(); }
  // Vertices whose weights were renormalised beyond rounding (WeightPolicy::kNormalize).
  uint32_t normalized_vertices() const { return normalized_vertices_; }
  uint64_t byte_size() const;

 private:
  Mesh() = default;
  std::string id_;
  uint32_t vertex_count_ = 0;
  uint32_t influences_ = 0;
  uint32_t joint_count_ = 0;
  uint32_t normalized_vertices_ = 0;
  AlignedBuffer<float> positions_;
  AlignedBuffer<float> normals_;
  AlignedBuffer<uint16_t> joints_;
  AlignedBuffer<float> weights_;
};

}  // namespace skinserve
