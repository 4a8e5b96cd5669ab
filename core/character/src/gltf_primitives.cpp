// Primitives: vertex attributes, joint indices and weights, triangle indices. Skinned ones
// (a mesh node with a skin) and rigid parts (a mesh node without one: every vertex follows
// that node, one influence of weight 1).
#include <fmt/format.h>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <limits>
#include <optional>

#include "gltf_accessor.h"
#include "gltf_parts.h"
#include "skinserve/model/mesh.h"

namespace skinserve::gltf {
namespace {

constexpr int kInfluencesPerSet = 4;  // JOINTS_n and WEIGHTS_n are VEC4
constexpr int kMaxSets = static_cast<int>(kMaxInfluences) / kInfluencesPerSet;
// How far a TANGENT's xyz length and |w| may be from 1 to be renormalised (snapped); see
// ReadTangents.
constexpr float kGltfTangentTolerance = kTangentLengthTolerance;

// The accessor of attribute `name`, or nullopt when the primitive has none.
std::optional<int> Attribute(const tinygltf::Primitive& p, const std::string& name) {
  const auto it = p.attributes.find(name);
  if (it == p.attributes.end()) return std::nullopt;
  return it->second;
}

// How `reader`'s accessor stores its values (the types the importer accepts for vertex
// attributes; any other reads as kNone).
StoredAttribute Stored(const AccessorReader& reader) {
  StoredType type = StoredType::kNone;
  switch (reader.component_type()) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      type = StoredType::kFloat;
      break;
    case TINYGLTF_COMPONENT_TYPE_BYTE:
      type = StoredType::kByte;
      break;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      type = StoredType::kUnsignedByte;
      break;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
      type = StoredType::kShort;
      break;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      type = StoredType::kUnsignedShort;
      break;
    default:
      break;
  }
  return {.type = type, .normalized = reader.normalized()};
}

// The wider of two WEIGHTS_n sets' storage: FLOAT over UNSIGNED_SHORT over UNSIGNED_BYTE.
StoredAttribute WiderWeights(StoredAttribute a, StoredAttribute b) {
  auto rank = [](StoredType t) {
    return t == StoredType::kFloat           ? 3
           : t == StoredType::kUnsignedShort ? 2
           : t == StoredType::kUnsignedByte  ? 1
                                             : 0;
  };
  if (rank(b.type) > rank(a.type)) return b;
  if (rank(b.type) == rank(a.type)) return {a.type, a.normalized && b.normalized};
  return a;
}

Result<AccessorReader> OpenAttribute(const tinygltf::Model& model, int accessor,
                                     const std::string& what, int type,
                                     std::initializer_list<int> component_types,
                                     std::size_t vertex_count) {
  auto reader = AccessorReader::Open(model, accessor, what, type, component_types);
  if (reader.ok() && reader->count() != vertex_count) {
    return InvalidArgument(fmt::format("{}: accessor {} has count {}; POSITION has {} vertices",
                                       what, accessor, reader->count(), vertex_count));
  }
  return reader;
}

// How many JOINTS_n/WEIGHTS_n pairs the primitive has (0: not skinned); both of a pair, and
// the pairs numbered from 0 without gaps, or an error.
Result<int> CountInfluenceSets(const tinygltf::Primitive& p, const std::string& what) {
  int sets = 0;
  while (Attribute(p, fmt::format("JOINTS_{}", sets)) ||
         Attribute(p, fmt::format("WEIGHTS_{}", sets))) {
    if (!Attribute(p, fmt::format("JOINTS_{}", sets)) ||
        !Attribute(p, fmt::format("WEIGHTS_{}", sets))) {
      return InvalidArgument(fmt::format(
          "{}: has only one of JOINTS_{} and WEIGHTS_{}; skinning needs both", what, sets, sets));
    }
    ++sets;
  }
  for (const auto& [name, accessor] : p.attributes) {
    int n = 0;
    if ((std::sscanf(name.c_str(), "JOINTS_%d", &n) == 1 ||
         std::sscanf(name.c_str(), "WEIGHTS_%d", &n) == 1) &&
        n >= sets) {
      return InvalidArgument(fmt::format(
          "{}.attributes.{}: without set {} before it, or past the {} influences supported "
          "(JOINTS_0..{})",
          what, name, sets, kMaxInfluences, kMaxSets - 1));
    }
  }
  if (sets > kMaxSets) {
    return InvalidArgument(fmt::format("{}: has {} JOINTS_n sets; at most {} ({} influences)", what,
                                       sets, kMaxSets, kMaxInfluences));
  }
  return sets;
}

// Component types a morph target's NORMAL and TANGENT deltas may have: floats, or
// KHR_mesh_quantization's signed normalized bytes and shorts.
constexpr std::initializer_list<int> kDirectionDeltaTypes = {
    TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE, TINYGLTF_COMPONENT_TYPE_SHORT};

// An integer direction (NORMAL, TANGENT, or their deltas) must be flagged normalized:
// KHR_mesh_quantization allows no other integer form for them.
Status CheckNormalizedDirection(const AccessorReader& reader, const std::string& field) {
  if (reader.component_type() == TINYGLTF_COMPONENT_TYPE_FLOAT || reader.normalized()) {
    return Status::Ok();
  }
  return InvalidArgument(fmt::format(
      "{}: accessor {} has componentType {} without normalized: true; integer directions must "
      "be normalized (KHR_mesh_quantization)",
      field, reader.index(), ComponentTypeName(reader.component_type())));
}

// The primitive's morph targets into `a` (which holds its positions, normals and tangents),
// dense deltas made sparse: a vertex is listed in a target when one of its deltas is not
// zero. NORMAL (TANGENT) deltas are kept when the primitive has normals (tangents) and a
// target moves them (zeros for the targets that do not).
Status ReadMorphTargets(const tinygltf::Model& model, const tinygltf::Primitive& p,
                        const std::string& what, MeshArrays* a) {
  if (p.targets.empty()) return Status::Ok();
  if (p.targets.size() > kMaxMorphTargets) {
    return InvalidArgument(fmt::format("{}.targets: {} targets; at most {}", what, p.targets.size(),
                                       kMaxMorphTargets));
  }
  const std::size_t v_count = a->vertex_count;
  bool normals = false, tangents = false;
  for (const auto& target : p.targets) {
    normals |= target.count("NORMAL") > 0;
    tangents |= target.count("TANGENT") > 0;
  }
  normals &= !a->normals.empty();
  tangents &= !a->tangents.empty();  // without TANGENT (or NORMAL) there is nothing to move
  std::vector<float> dp(3 * v_count), dn(normals ? 3 * v_count : 0), dt(tangents ? 3 * v_count : 0);
  for (std::size_t t = 0; t < p.targets.size(); ++t) {
    const auto& target = p.targets[t];
    std::fill(dp.begin(), dp.end(), 0.0f);
    std::fill(dn.begin(), dn.end(), 0.0f);
    std::fill(dt.begin(), dt.end(), 0.0f);
    for (const auto& [name, accessor] : target) {
      std::vector<float>* deltas = name == "POSITION"  ? &dp
                                   : name == "NORMAL"  ? &dn
                                   : name == "TANGENT" ? &dt
                                                       : nullptr;
      if (deltas == nullptr || deltas->empty()) continue;  // other attributes, or unused
      const std::string field = fmt::format("{}.targets[{}].{}", what, t, name);
      auto reader =
          OpenAttribute(model, accessor, field, TINYGLTF_TYPE_VEC3,
                        deltas == &dp ? std::initializer_list<int>{TINYGLTF_COMPONENT_TYPE_FLOAT}
                                      : kDirectionDeltaTypes,
                        v_count);
      if (!reader.ok()) return reader.status();
      if (Status s = CheckNormalizedDirection(*reader, field); !s.ok()) return s;
      for (std::size_t v = 0; v < v_count; ++v) {
        for (int c = 0; c < 3; ++c) (*deltas)[3 * v + c] = reader->Normalized(v, c);
      }
    }
    uint32_t size = 0;
    for (std::size_t v = 0; v < v_count; ++v) {
      bool moves = false;
      for (int c = 0; c < 3; ++c) {
        moves |= dp[3 * v + c] != 0.0f || (normals && dn[3 * v + c] != 0.0f) ||
                 (tangents && dt[3 * v + c] != 0.0f);
      }
      if (!moves) continue;
      ++size;
      a->morph_indices.push_back(static_cast<uint32_t>(v));
      a->morph_position_deltas.insert(a->morph_position_deltas.end(), &dp[3 * v], &dp[3 * v] + 3);
      if (normals) {
        a->morph_normal_deltas.insert(a->morph_normal_deltas.end(), &dn[3 * v], &dn[3 * v] + 3);
      }
      if (tangents) {
        a->morph_tangent_deltas.insert(a->morph_tangent_deltas.end(), &dt[3 * v], &dt[3 * v] + 3);
      }
    }
    a->morph_target_sizes.push_back(size);
  }
  return Status::Ok();
}

// TANGENT into a->tangents (a->normals already read). Exporters write tangents that are
// unit only to their float (or 8/16-bit) precision, so xyz is renormalised when its length
// is within kGltfTangentTolerance of 1 (the engine's own kTangentLengthTolerance: what it
// would accept as is), and w is snapped to +-1 when within the same of it; anything farther
// is not a tangent the exporter meant and is refused naming the accessor and the vertex.
Status ReadTangents(const tinygltf::Model& model, int accessor, const std::string& what,
                    MeshArrays* a) {
  const std::string field = what + ".attributes.TANGENT";
  const std::size_t v_count = a->vertex_count;
  // KHR_mesh_quantization: signed normalized bytes or shorts besides floats.
  auto reader = OpenAttribute(
      model, accessor, field, TINYGLTF_TYPE_VEC4,
      {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE, TINYGLTF_COMPONENT_TYPE_SHORT},
      v_count);
  if (!reader.ok()) return reader.status();
  if (Status s = CheckNormalizedDirection(*reader, field); !s.ok()) return s;
  a->tangents.resize(4 * v_count);
  for (std::size_t v = 0; v < v_count; ++v) {
    double t[4];
    for (int c = 0; c < 4; ++c) t[c] = reader->Normalized(v, c);
    const double length = std::sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
    if (!(std::fabs(length - 1.0) <= kGltfTangentTolerance)) {
      return InvalidArgument(
          fmt::format("{}: accessor {} vertex {} xyz has length {:.6g}; a tangent must be a unit "
                      "vector within {}",
                      field, accessor, v, length, kGltfTangentTolerance));
    }
    if (!(std::fabs(std::fabs(t[3]) - 1.0) <= kGltfTangentTolerance)) {
      return InvalidArgument(
          fmt::format("{}: accessor {} vertex {} w = {:.6g}; the handedness must be +1 or -1 "
                      "within {}",
                      field, accessor, v, t[3], kGltfTangentTolerance));
    }
    for (int c = 0; c < 3; ++c) a->tangents[4 * v + c] = static_cast<float>(t[c] / length);
    a->tangents[4 * v + 3] = t[3] > 0 ? 1.0f : -1.0f;
  }
  return Status::Ok();
}

// POSITION into out->arrays (vertex_count and positions) and out->stored.
Status ReadPositions(const tinygltf::Model& model, const tinygltf::Primitive& p,
                     const std::string& what, SkinnedPrimitive* out) {
  const std::optional<int> position = Attribute(p, "POSITION");
  if (!position) return InvalidArgument(what + ".attributes has no POSITION");
  // KHR_mesh_quantization: integer positions, normalized or not (a node transform or the
  // inverse bind matrices then scale them back); Value() reads them as the flag says.
  auto positions =
      AccessorReader::Open(model, *position, what + ".attributes.POSITION", TINYGLTF_TYPE_VEC3,
                           {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE,
                            TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_SHORT,
                            TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT});
  if (!positions.ok()) return positions.status();
  const std::size_t v_count = positions->count();
  if (v_count > std::numeric_limits<uint32_t>::max()) {
    return InvalidArgument(fmt::format("{}.attributes.POSITION: {} vertices; at most {}", what,
                                       v_count, std::numeric_limits<uint32_t>::max()));
  }
  MeshArrays& a = out->arrays;
  out->stored.position = Stored(*positions);
  a.vertex_count = static_cast<uint32_t>(v_count);
  a.positions.resize(3 * v_count);
  for (std::size_t v = 0; v < v_count; ++v) {
    for (int c = 0; c < 3; ++c) a.positions[3 * v + c] = positions->Value(v, c);
  }
  return Status::Ok();
}

// NORMAL, then TANGENT (ignored, with a warning, without NORMAL), into out->arrays.
Status ReadNormalsAndTangents(const tinygltf::Model& model, const tinygltf::Primitive& p,
                              const std::string& what, SkinnedPrimitive* out) {
  MeshArrays& a = out->arrays;
  const std::size_t v_count = a.vertex_count;
  if (const std::optional<int> normal = Attribute(p, "NORMAL")) {
    // KHR_mesh_quantization: signed normalized bytes or shorts besides floats.
    auto normals = OpenAttribute(model, *normal, what + ".attributes.NORMAL", TINYGLTF_TYPE_VEC3,
                                 {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE,
                                  TINYGLTF_COMPONENT_TYPE_SHORT},
                                 v_count);
    if (!normals.ok()) return normals.status();
    if (normals->component_type() != TINYGLTF_COMPONENT_TYPE_FLOAT && !normals->normalized()) {
      return InvalidArgument(fmt::format(
          "{}.attributes.NORMAL: accessor {} has componentType {} without normalized: true; "
          "integer normals must be normalized (KHR_mesh_quantization)",
          what, *normal, ComponentTypeName(normals->component_type())));
    }
    out->stored.normal = Stored(*normals);
    a.normals.resize(3 * v_count);
    for (std::size_t v = 0; v < v_count; ++v) {
      for (int c = 0; c < 3; ++c) a.normals[3 * v + c] = normals->Normalized(v, c);
    }
  }
  if (const std::optional<int> tangent = Attribute(p, "TANGENT")) {
    // The spec: without NORMAL, a client computes flat normals and MUST ignore TANGENT.
    if (a.normals.empty()) {
      out->warnings.push_back(
          fmt::format("{}.attributes.TANGENT ignored: the primitive has no NORMAL, and glTF "
                      "ignores tangents without normals",
                      what));
    } else if (Status s = ReadTangents(model, *tangent, what, &a); !s.ok()) {
      return s;
    }
  }
  return Status::Ok();
}

// JOINTS_set and WEIGHTS_set into influences 4 * set .. 4 * set + 3 of every vertex of
// out->arrays (joints and weights already sized); each joint below `joint_count`, each
// weight finite and >= 0.
Status ReadInfluenceSet(const tinygltf::Model& model, const tinygltf::Primitive& p,
                        const std::string& what, int set, uint32_t joint_count,
                        SkinnedPrimitive* out) {
  MeshArrays& a = out->arrays;
  const std::size_t v_count = a.vertex_count;
  const std::size_t b = a.influences;
  const std::string joints_name = fmt::format("{}.attributes.JOINTS_{}", what, set);
  const std::string weights_name = fmt::format("{}.attributes.WEIGHTS_{}", what, set);
  auto joints = OpenAttribute(
      model, *Attribute(p, fmt::format("JOINTS_{}", set)), joints_name, TINYGLTF_TYPE_VEC4,
      {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT}, v_count);
  if (!joints.ok()) return joints.status();
  // The spec requires integer weights to be normalized; they are read as such either way,
  // and the sum is renormalised below, so the flag cannot change the result.
  auto weights = OpenAttribute(
      model, *Attribute(p, fmt::format("WEIGHTS_{}", set)), weights_name, TINYGLTF_TYPE_VEC4,
      {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
       TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT},
      v_count);
  if (!weights.ok()) return weights.status();
  out->stored.weights =
      set == 0 ? Stored(*weights) : WiderWeights(out->stored.weights, Stored(*weights));
  for (std::size_t v = 0; v < v_count; ++v) {
    for (int c = 0; c < kInfluencesPerSet; ++c) {
      const std::size_t k = v * b + static_cast<std::size_t>(set * kInfluencesPerSet + c);
      const uint32_t joint = joints->Uint(v, c);
      if (joint >= joint_count) {
        return InvalidArgument(
            fmt::format("{}: vertex {} influence {} is joint {}, past the skin's {} joints",
                        joints_name, v, c, joint, joint_count));
      }
      const float w = weights->Normalized(v, c);
      if (!std::isfinite(w) || w < 0.0f) {
        return InvalidArgument(
            fmt::format("{}: vertex {} influence {} is {}; weights must be finite and >= 0",
                        weights_name, v, c, w));
      }
      a.joints[k] = static_cast<uint16_t>(joint);
      a.weights[k] = w;
    }
  }
  return Status::Ok();
}

// Every vertex's weights are divided by their sum. The spec asks for a sum of 1, but
// quantized (UNSIGNED_BYTE) weights and exporters' rounding miss it by more than
// Mesh::Create's kWeightSumTolerance (1e-3), which it rejects by default; dividing here
// makes the importer's output pass that validator, and leaves a weight sum of exactly 1
// up to float rounding, so skinning never scales a vertex.
Status NormalizeWeightSums(const std::string& what, MeshArrays* a) {
  const std::size_t b = a->influences;
  for (std::size_t v = 0; v < a->vertex_count; ++v) {
    double sum = 0;
    for (std::size_t i = 0; i < b; ++i) sum += a->weights[v * b + i];
    if (!(sum > 0)) {
      return InvalidArgument(fmt::format(
          "{}.attributes.WEIGHTS_n: vertex {} has all weights zero; each vertex needs one > 0",
          what, v));
    }
    for (std::size_t i = 0; i < b; ++i) {
      a->weights[v * b + i] = static_cast<float>(a->weights[v * b + i] / sum);
    }
  }
  return Status::Ok();
}

// The triangles' indices into out->indices (without indices: the vertices in order), each
// below the vertex count, a multiple of 3 in all.
Status ReadIndices(const tinygltf::Model& model, const tinygltf::Primitive& p,
                   const std::string& what, SkinnedPrimitive* out) {
  const std::size_t v_count = out->arrays.vertex_count;
  if (p.indices >= 0) {
    auto indices = AccessorReader::Open(
        model, p.indices, what + ".indices", TINYGLTF_TYPE_SCALAR,
        {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
         TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT});
    if (!indices.ok()) return indices.status();
    out->indices.resize(indices->count());
    for (std::size_t i = 0; i < indices->count(); ++i) {
      const uint32_t index = indices->Uint(i, 0);
      if (index >= v_count) {
        return InvalidArgument(fmt::format("{}.indices[{}] = {} is not below the {} vertices", what,
                                           i, index, v_count));
      }
      out->indices[i] = index;
    }
  } else {
    out->indices.resize(v_count);
    for (std::size_t i = 0; i < v_count; ++i) out->indices[i] = static_cast<uint32_t>(i);
  }
  if (out->indices.size() % 3 != 0) {
    return InvalidArgument(
        fmt::format("{}: {} triangle indices is not a multiple of 3", what, out->indices.size()));
  }
  return Status::Ok();
}

Status ReadSkinnedPrimitive(const tinygltf::Model& model, const tinygltf::Primitive& p,
                            const std::string& what, int sets, uint32_t joint_count,
                            SkinnedPrimitive* out) {
  if (p.mode != TINYGLTF_MODE_TRIANGLES) {
    return InvalidArgument(fmt::format("{}.mode is {}; only triangles ({}) are supported", what,
                                       p.mode, TINYGLTF_MODE_TRIANGLES));
  }
  if (Status s = ReadPositions(model, p, what, out); !s.ok()) return s;
  MeshArrays& a = out->arrays;
  const std::size_t v_count = a.vertex_count;
  a.influences = static_cast<uint32_t>(sets * kInfluencesPerSet);
  a.joint_count = joint_count;
  if (Status s = ReadNormalsAndTangents(model, p, what, out); !s.ok()) return s;

  // A rigid part (no skin): one influence, joint 0 (the node it follows), weight 1.
  if (sets == 0) {
    a.influences = 1;
    a.joints.assign(v_count, 0);
    a.weights.assign(v_count, 1.0f);
  }
  const std::size_t b = a.influences;
  a.joints.resize(b * v_count);
  a.weights.resize(b * v_count);
  for (int set = 0; set < sets; ++set) {
    if (Status s = ReadInfluenceSet(model, p, what, set, joint_count, out); !s.ok()) return s;
  }
  if (sets > 0) {
    if (Status s = NormalizeWeightSums(what, &a); !s.ok()) return s;
  }
  if (Status s = ReadIndices(model, p, what, out); !s.ok()) return s;
  if (Status s = ReadMorphTargets(model, p, what, &a); !s.ok()) return s;

  // The engine's own validator, with no operator limits: what it rejects here (e.g. a zero
  // normal) would be rejected at upload, so say so now, naming the primitive.
  MeshOptions unlimited;
  unlimited.limits.max_vertices = std::numeric_limits<uint32_t>::max();
  unlimited.limits.max_joints = kMaxJointsLimit;
  if (auto mesh = Mesh::Create(a, unlimited); !mesh.ok()) {
    return InvalidArgument(fmt::format("{}: {}", what, mesh.status().message()));
  }
  return Status::Ok();
}

}  // namespace

Result<std::vector<SkinnedPrimitive>> ImportSkinnedPrimitives(
    const tinygltf::Model& model, const std::vector<CharacterSkin>& skins) {
  std::vector<SkinnedPrimitive> primitives;
  for (std::size_t n = 0; n < model.nodes.size(); ++n) {
    const tinygltf::Node& node = model.nodes[n];
    if (node.mesh < 0) continue;
    if (static_cast<std::size_t>(node.mesh) >= model.meshes.size()) {
      return InvalidArgument(fmt::format("nodes[{}].mesh = {} is not a mesh (the file has {})", n,
                                         node.mesh, model.meshes.size()));
    }
    // A mesh node without a skin is a rigid part: its vertices follow the node (a glTF
    // viewer draws it so, with JOINTS_n/WEIGHTS_n, if any, unused).
    const bool rigid = node.skin < 0;
    if (!rigid && static_cast<std::size_t>(node.skin) >= skins.size()) {
      return InvalidArgument(fmt::format("nodes[{}].skin = {} is not a skin (the file has {})", n,
                                         node.skin, skins.size()));
    }
    const tinygltf::Mesh& mesh = model.meshes[static_cast<std::size_t>(node.mesh)];
    const uint32_t joint_count =
        rigid ? 1u
              : static_cast<uint32_t>(skins[static_cast<std::size_t>(node.skin)].joints.size());
    for (std::size_t p = 0; p < mesh.primitives.size(); ++p) {
      const std::string what = fmt::format("meshes[{}].primitives[{}]", node.mesh, p);
      int sets = 0;
      if (!rigid) {
        auto counted = CountInfluenceSets(mesh.primitives[p], what);
        if (!counted.ok()) return counted.status();
        // A primitive of a skinned mesh without joints and weights is not skinned, and
        // breaks the spec's rule for skinned meshes: it is left out.
        if (*counted == 0) continue;
        sets = *counted;
      }
      SkinnedPrimitive out;
      out.name = fmt::format(
          "{}/{}", mesh.name.empty() ? fmt::format("meshes[{}]", node.mesh) : mesh.name, p);
      out.node = static_cast<int>(n);
      out.skin = rigid ? -1 : node.skin;
      if (Status s = ReadSkinnedPrimitive(model, mesh.primitives[p], what, sets, joint_count, &out);
          !s.ok()) {
        return s;
      }
      primitives.push_back(std::move(out));
    }
  }
  if (primitives.empty()) {
    return InvalidArgument(
        "the file has no primitive to skin (a node with a mesh: with a skin and JOINTS_0 and "
        "WEIGHTS_0, or without a skin as a rigid part)");
  }
  return primitives;
}

}  // namespace skinserve::gltf
