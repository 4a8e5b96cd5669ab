#include "workload.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "skinserve/character/animation.h"
#include "skinserve/character/character_mesh.h"
#include "skinserve/character/gltf_import.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/reference/synthetic_morph.h"

namespace skinserve::load {

Status SetRestEncoding(Workload* w, RestEncoding encoding) {
  // A character's tangents not asked back (--tangents) stay out of a quantized rest stream
  // instead of costing it 8 bytes a vertex for nothing.
  if (encoding != RestEncoding::kFloat32 && !w->tangents && !w->arrays->tangents.empty()) {
    auto arrays = std::make_shared<MeshArrays>(*w->arrays);
    arrays->tangents.clear();
    arrays->morph_tangent_deltas.clear();
    w->arrays = std::move(arrays);
  }
  auto mesh = Mesh::Create(*w->arrays, {.rest_encoding = encoding});
  if (!mesh.ok()) return mesh.status();
  w->mesh = *mesh;
  w->rest_encoding = encoding;
  return Status::Ok();
}

Status ChooseRestEncoding(Workload* w, std::optional<RestEncoding> asked) {
  RestEncodingChoice choice = DecideRestEncoding(asked, w->file_rest_encoding);
  if (choice.encoding != w->rest_encoding) {
    if (Status s = SetRestEncoding(w, choice.encoding); !s.ok()) {
      return Status(s.code(),
                    fmt::format("rest encoding {} ({}): {}", RestEncodingName(choice.encoding),
                                choice.reason, s.message()));
    }
  }
  w->rest_encoding_reason = std::move(choice.reason);
  return Status::Ok();
}

Workload MakeWorkload(uint32_t vertices, uint32_t bones, uint32_t joints, bool normals,
                      uint64_t seed, SkinningMethod method, const MorphWorkload& morph,
                      bool tangents) {
  Workload w;
  w.vertices = vertices;
  w.bones = bones;
  w.joints = joints;
  w.normals = normals;
  w.tangents = tangents && normals;
  w.method = method;
  MeshArrays arrays = MakeSyntheticMesh({.vertex_count = vertices,
                                         .influences = bones,
                                         .joint_count = joints,
                                         .normals = normals,
                                         .tangents = w.tangents,
                                         .seed = seed});
  if (morph.targets > 0) {
    AddSyntheticMorphTargets(
        {.targets = morph.targets, .fraction = morph.coverage, .normals = normals, .seed = seed},
        &arrays);
    for (int f = 0; morph.active > 0 && f < kDistinctPalettes; ++f) {
      w.morph_weights.push_back(MakeMorphWeights(morph.targets, morph.active, seed, f));
    }
  }
  w.arrays = std::make_shared<const MeshArrays>(std::move(arrays));
  auto mesh = Mesh::Create(*w.arrays);
  if (!mesh.ok()) throw std::runtime_error(mesh.status().ToString());
  w.mesh = *mesh;
  for (int f = 0; f < kDistinctPalettes; ++f) {
    w.palettes.push_back(method == SkinningMethod::kDualQuaternion
                             ? MakeRigidPalette(joints, seed, f)
                             : MakeSyntheticPalette(joints, seed, f));
  }
  return w;
}

namespace {

// The character's meshes as one: vertices one after another, each mesh's joint indices
// shifted past the joints of the meshes before it, so that one palette (the meshes'
// palettes one after another) skins them all in one request per frame. Normals (tangents)
// only when every mesh has them. Morph targets follow too: each mesh's after the meshes'
// before it, their vertex indices shifted likewise (normal or tangent deltas 0 for a mesh
// whose targets have none, when another's have them).
MeshArrays MergeMeshes(const std::vector<CharacterMesh>& meshes) {
  if (meshes.size() == 1) return meshes.front().arrays;
  MeshArrays merged;
  bool normals = true, morph_normals = false, tangents = true, morph_tangents = false;
  for (const CharacterMesh& m : meshes) {
    merged.influences = std::max(merged.influences, m.arrays.influences);
    normals = normals && !m.arrays.normals.empty();
    morph_normals = morph_normals || !m.arrays.morph_normal_deltas.empty();
    tangents = tangents && !m.arrays.tangents.empty();
    morph_tangents = morph_tangents || !m.arrays.morph_tangent_deltas.empty();
  }
  morph_normals = morph_normals && normals;
  tangents = tangents && normals;
  morph_tangents = morph_tangents && tangents;
  // `count` deltas of a mesh (empty: zeros) appended to the merged ones.
  auto append_deltas = [](const std::vector<float>& part, std::size_t count,
                          std::vector<float>* all) {
    if (part.empty()) {
      all->resize(all->size() + count, 0.0f);
    } else {
      all->insert(all->end(), part.begin(), part.end());
    }
  };
  for (const CharacterMesh& m : meshes) {
    const MeshArrays& a = m.arrays;
    const auto base = static_cast<uint32_t>(merged.vertex_count);
    merged.vertex_count += a.vertex_count;
    merged.morph_target_sizes.insert(merged.morph_target_sizes.end(), a.morph_target_sizes.begin(),
                                     a.morph_target_sizes.end());
    for (uint32_t index : a.morph_indices) merged.morph_indices.push_back(base + index);
    merged.morph_position_deltas.insert(merged.morph_position_deltas.end(),
                                        a.morph_position_deltas.begin(),
                                        a.morph_position_deltas.end());
    if (morph_normals) {
      append_deltas(a.morph_normal_deltas, a.morph_position_deltas.size(),
                    &merged.morph_normal_deltas);
    }
    if (morph_tangents) {
      append_deltas(a.morph_tangent_deltas, a.morph_position_deltas.size(),
                    &merged.morph_tangent_deltas);
    }
  }
  merged.vertex_count = 0;
  for (const CharacterMesh& m : meshes) {
    const MeshArrays& a = m.arrays;
    merged.positions.insert(merged.positions.end(), a.positions.begin(), a.positions.end());
    if (normals) merged.normals.insert(merged.normals.end(), a.normals.begin(), a.normals.end());
    if (tangents) {
      merged.tangents.insert(merged.tangents.end(), a.tangents.begin(), a.tangents.end());
    }
    for (std::size_t v = 0; v < a.vertex_count; ++v) {
      for (std::size_t i = 0; i < merged.influences; ++i) {
        const bool real = i < a.influences;
        merged.joints.push_back(static_cast<uint16_t>(merged.joint_count +
                                                      (real ? a.joints[v * a.influences + i] : 0)));
        merged.weights.push_back(real ? a.weights[v * a.influences + i] : 0.0f);
      }
    }
    merged.vertex_count += a.vertex_count;
    merged.joint_count += a.joint_count;
  }
  return merged;
}

// The meshes' triangles into MergeMeshes' vertices: each mesh's after the vertices of the
// meshes before it.
std::vector<uint32_t> MergeIndices(const std::vector<CharacterMesh>& meshes) {
  std::vector<uint32_t> indices;
  uint32_t first_vertex = 0;
  for (const CharacterMesh& m : meshes) {
    for (uint32_t index : m.indices) indices.push_back(first_vertex + index);
    first_vertex += static_cast<uint32_t>(m.arrays.vertex_count);
  }
  return indices;
}

}  // namespace

Result<Workload> MakeGltfWorkload(const std::string& path, int primitive, bool normals,
                                  bool tangents) {
  auto character = LoadGltfFile(path);
  if (!character.ok()) {
    // The importer names the file itself in most errors: never twice.
    if (character.status().message().starts_with(path + ":")) return character.status();
    return Status(character.status().code(),
                  fmt::format("{}: {}", path, character.status().message()));
  }
  PrintImportWarnings(*character, path);
  if (primitive >= static_cast<int>(character->primitives.size())) {
    return InvalidArgument(
        fmt::format("--primitive {} is not below the {} primitive(s) (skinned and rigid) of {}",
                    primitive, character->primitives.size(), path));
  }
  auto meshes = CharacterMeshes(*character, primitive);
  if (!meshes.ok()) return meshes.status();
  uint64_t joints = 0;
  for (const CharacterMesh& m : *meshes) {
    if (normals && m.arrays.normals.empty()) {
      return InvalidArgument(fmt::format("--normals: {} has no normals in {}", m.name, path));
    }
    if (tangents && m.arrays.tangents.empty()) {
      return InvalidArgument(fmt::format("--tangents: {} has no tangents in {}", m.name, path));
    }
    joints += m.arrays.joint_count;
  }
  if (joints > kMaxJointsLimit) {
    return InvalidArgument(
        fmt::format("{}: its skins have {} joints together; one mesh holds at "
                    "most {}",
                    path, joints, kMaxJointsLimit));
  }
  const AnimationClip* clip = character->FindClip("");
  if (clip == nullptr) return InvalidArgument(fmt::format("{} has no animation clip", path));

  Workload w;
  std::vector<int> uploaded;
  for (const CharacterMesh& m : *meshes) {
    for (const PrimitiveSpan& part : m.parts) uploaded.push_back(part.primitive);
  }
  w.file_rest_encoding = RestEncodingFromFile(*character, uploaded);
  w.arrays = std::make_shared<const MeshArrays>(MergeMeshes(*meshes));
  w.indices = MergeIndices(*meshes);
  w.vertices = w.arrays->vertex_count;
  w.bones = w.arrays->influences;
  w.joints = w.arrays->joint_count;
  w.normals = normals;
  w.tangents = tangents;
  auto mesh = Mesh::Create(*w.arrays);
  if (!mesh.ok()) {
    return Status(mesh.status().code(), fmt::format("{}: {}", path, mesh.status().message()));
  }
  w.mesh = *mesh;
  // One palette (and one set of morph weights) per 1/30 s of the clip; frame f % size wraps
  // around its duration.
  const auto count =
      static_cast<int>(std::clamp(std::ceil(clip->duration * kGltfWorkloadFps), 1.0, 3600.0));
  std::vector<MorphWeight> mesh_weights;
  for (int f = 0; f < count; ++f) {
    const Pose pose = SampleClip(*character, *clip, f / kGltfWorkloadFps);
    auto palettes = MeshPalettes(*character, pose, *meshes);
    if (!palettes.ok()) return palettes.status();
    std::vector<float> palette;
    for (const std::vector<float>& p : *palettes) palette.insert(palette.end(), p.begin(), p.end());
    w.palettes.push_back(std::move(palette));
    if (w.mesh->morph_target_count() == 0) continue;
    std::vector<MorphWeight> weights;
    uint32_t target_base = 0;
    for (const CharacterMesh& m : *meshes) {
      MeshMorphWeights(m, pose, &mesh_weights);
      for (MorphWeight mw : mesh_weights) weights.push_back({target_base + mw.target, mw.weight});
      target_base += static_cast<uint32_t>(m.morph_sources.size());
    }
    w.morph_weights.push_back(std::move(weights));
  }
  return w;
}

}  // namespace skinserve::load
