// Mesh: a skinned mesh, validated on ingest and immutable afterwards.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "skinserve/model/aligned_buffer.h"
#include "skinserve/model/morph_targets.h"
#include "skinserve/model/quantized_rest.h"
#include "skinserve/model/status.h"

namespace skinserve {

inline constexpr uint32_t kMaxInfluences = 8;       // B: influences per vertex, 1..8
inline constexpr uint32_t kMaxJointsLimit = 65535;  // joint indices are uint16
inline constexpr float kWeightSumTolerance = 1e-3f;
// A tangent's xyz is a unit vector within this (|length - 1|): loose enough for tangents an
// exporter quantized to 8 bits, tight enough to catch a missing normalisation.
inline constexpr float kTangentLengthTolerance = 1e-2f;

// Limits an operator sets; checked before anything is allocated.
struct MeshLimits {
  uint32_t max_vertices = 4'000'000;
  uint32_t max_joints = 1024;
  uint32_t max_morph_targets = kMaxMorphTargets;  // at most kMaxMorphTargets
  uint64_t max_morph_deltas = 16'000'000;         // all targets' deltas together
};

// What to do with a vertex whose weights do not sum to 1 within kWeightSumTolerance.
enum class WeightPolicy {
  kReject,     // INVALID_ARGUMENT naming the vertex (the default)
  kNormalize,  // divide by the sum and count it in Mesh::normalized_vertices()
};

struct MeshOptions {
  MeshLimits limits;
  WeightPolicy weight_policy = WeightPolicy::kReject;
  // kFloat32, or a quantized rest stream built beside the float arrays, which then hold
  // the values it decodes to (quantized_rest.h). Not with morph targets.
  RestEncoding rest_encoding = RestEncoding::kFloat32;
};

// A mesh as plain arrays, before validation. Field names match the wire contract.
//  - positions: 3 * vertex_count floats, x y z per vertex, finite.
//  - normals:   empty, or 3 * vertex_count finite floats (renormalised after skinning).
//  - tangents:  empty, or 4 * vertex_count finite floats, x y z w per vertex as glTF's
//               TANGENT: xyz a unit vector (within kTangentLengthTolerance), skinned like
//               the normal; w the bitangent's handedness, exactly +1 or -1, kept as is.
//               Tangents need normals (glTF ignores tangents without them).
//  - joints:    influences * vertex_count indices, vertex-major (joints[v * B + i]), each
//               < joint_count. Unused influences are padding: weight 0, any valid index.
//  - weights:   influences * vertex_count floats, vertex-major, each >= 0, summing to 1
//               per vertex within kWeightSumTolerance (within it they are renormalised to
//               sum exactly 1; beyond it see WeightPolicy).
// Morph targets (morph_targets.h), stored sparse: each target lists only the vertices it
// moves. All targets' deltas lie back to back in target order:
//  - morph_target_sizes:    one count per target (T <= max_morph_targets), each <= vertex_count;
//                           their sum D <= max_morph_deltas. Empty: no targets.
//  - morph_indices:         D vertex indices, strictly ascending within each target.
//  - morph_position_deltas: 3 * D finite floats, x y z per delta, each component within
//                           kMorphDeltaRange * max(1, the rest box's diagonal).
//  - morph_normal_deltas:   empty, or 3 * D finite floats within +-kMaxMorphNormalDelta
//                           (the mesh must have normals); a target that moves no normal has
//                           zeros there.
//  - morph_tangent_deltas:  empty, or 3 * D finite floats (xyz only; w is never morphed)
//                           within +-kMaxMorphNormalDelta (the mesh must have tangents).
struct MeshArrays {
  uint32_t vertex_count = 0;
  uint32_t influences = 0;
  uint32_t joint_count = 0;
  std::vector<float> positions;
  std::vector<float> normals;
  std::vector<float> tangents;
  std::vector<uint16_t> joints;
  std::vector<float> weights;
  std::vector<uint32_t> morph_target_sizes;
  std::vector<uint32_t> morph_indices;
  std::vector<float> morph_position_deltas;
  std::vector<float> morph_normal_deltas;
  std::vector<float> morph_tangent_deltas;
};

// Checks the sizes a mesh declares before its arrays arrive (an upload's header).
Status CheckMeshHeader(uint64_t vertex_count, uint64_t influences, uint64_t joint_count,
                       const MeshLimits& limits);

// Checks the morph targets an upload declares before their arrays arrive: the target
// count, each target's size (<= vertex_count) and their sum against the limits; normal
// deltas need a mesh with normals, tangent deltas one with tangents.
Status CheckMorphHeader(std::span<const uint32_t> target_sizes, uint64_t vertex_count,
                        bool has_normals, bool morph_normals, const MeshLimits& limits,
                        bool has_tangents = false, bool morph_tangents = false);

// Checks that a mesh may take `encoding`: a quantized rest stream carries no morph targets
// (their float deltas are added to the float rest arrays, which the quantized loops skip).
Status CheckRestEncoding(RestEncoding encoding, uint64_t morph_targets);

// Bytes a mesh of this shape occupies once stored (its morph deltas included: they count
// against the mesh store's budget and, while uploading, the upload budget).
uint64_t MeshByteSize(uint64_t vertex_count, uint64_t influences, bool has_normals,
                      uint64_t morph_targets = 0, uint64_t morph_deltas = 0,
                      bool morph_normals = false,
                      RestEncoding rest_encoding = RestEncoding::kFloat32, uint64_t joint_count = 0,
                      bool has_tangents = false, bool morph_tangents = false);

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
  bool has_tangents() const { return !tangents_.empty(); }
  std::span<const float> positions() const { return positions_.span(); }
  std::span<const float> normals() const { return normals_.span(); }
  std::span<const float> tangents() const { return tangents_.span(); }  // 4 per vertex
  std::span<const uint16_t> joints() const { return joints_.span(); }
  std::span<const float> weights() const { return weights_.span(); }
  // Morph targets: target t's deltas are [morph_offsets()[t], morph_offsets()[t + 1]) of
  // morph_indices() (ascending vertex indices), morph_position_deltas() and, when
  // has_morph_normals(), morph_normal_deltas() (3 floats per delta), and when
  // has_morph_tangents(), morph_tangent_deltas() (3 floats per delta: xyz).
  uint32_t morph_target_count() const { return morph_target_count_; }
  bool has_morph_normals() const { return !morph_normal_deltas_.empty(); }
  bool has_morph_tangents() const { return !morph_tangent_deltas_.empty(); }
  std::span<const uint32_t> morph_offsets() const { return morph_offsets_.span(); }
  std::span<const uint32_t> morph_indices() const { return morph_indices_.span(); }
  std::span<const float> morph_position_deltas() const { return morph_position_deltas_.span(); }
  std::span<const float> morph_normal_deltas() const { return morph_normal_deltas_.span(); }
  std::span<const float> morph_tangent_deltas() const { return morph_tangent_deltas_.span(); }
  // Vertices whose weights were renormalised beyond rounding (WeightPolicy::kNormalize).
  uint32_t normalized_vertices() const { return normalized_vertices_; }
  // The quantized rest stream, or null (RestEncoding::kFloat32). When present, positions(),
  // normals() and weights() hold the values it decodes to.
  const QuantizedRest* quantized_rest() const { return quantized_ ? &*quantized_ : nullptr; }
  RestEncoding rest_encoding() const {
    return quantized_ ? quantized_->encoding : RestEncoding::kFloat32;
  }
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
  AlignedBuffer<float> tangents_;
  AlignedBuffer<uint16_t> joints_;
  AlignedBuffer<float> weights_;
  uint32_t morph_target_count_ = 0;
  AlignedBuffer<uint32_t> morph_offsets_;
  AlignedBuffer<uint32_t> morph_indices_;
  AlignedBuffer<float> morph_position_deltas_;
  AlignedBuffer<float> morph_normal_deltas_;
  AlignedBuffer<float> morph_tangent_deltas_;
  std::optional<QuantizedRest> quantized_;
};

}  // namespace skinserve
