#include "workload.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "skinserve/character/animation.h"
#include "skinserve/character/character_mesh.h"
#include "skinserve/character/gltf_import.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::load {

Workload MakeWorkload(uint32_t vertices, uint32_t bones, uint32_t joints, bool normals,
                      uint64_t seed, SkinningMethod method) {
  Workload w;
  w.vertices = vertices;
  w.bones = bones;
  w.joints = joints;
  w.normals = normals;
  w.method = method;
  w.arrays = std::make_shared<const MeshArrays>(MakeSyntheticMesh({.vertex_count = vertices,
                                                                   .influences = bones,
                                                                   .joint_count = joints,
                                                                   .normals = normals,
                                                                   .seed = seed}));
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
// palettes one after another) skins them all in one request per frame. Normals only when
// every mesh has them.
MeshArrays MergeMeshes(const std::vector<CharacterMesh>& meshes) {
  if (meshes.size() == 1) return meshes.front().arrays;
  MeshArrays merged;
  bool normals = true;
  for (const CharacterMesh& m : meshes) {
    merged.influences = std::max(merged.influences, m.arrays.influences);
    normals = normals && !m.arrays.normals.empty();
  }
  for (const CharacterMesh& m : meshes) {
    const MeshArrays& a = m.arrays;
    merged.positions.insert(merged.positions.end(), a.positions.begin(), a.positions.end());
    if (normals) merged.normals.insert(merged.normals.end(), a.normals.begin(), a.normals.end());
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

}  // namespace

Result<Workload> MakeGltfWorkload(const std::string& path, int primitive, bool normals) {
  auto character = LoadGltfFile(path);
  if (!character.ok()) {
    // The importer names the file itself in most errors: never twice.
    if (character.status().message().starts_with(path + ":")) return character.status();
    return Status(character.status().code(),
                  fmt::format("{}: {}", path, character.status().message()));
  }
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
  w.arrays = std::make_shared<const MeshArrays>(MergeMeshes(*meshes));
  w.vertices = w.arrays->vertex_count;
  w.bones = w.arrays->influences;
  w.joints = w.arrays->joint_count;
  w.normals = normals;
  auto mesh = Mesh::Create(*w.arrays);
  if (!mesh.ok()) {
    return Status(mesh.status().code(), fmt::format("{}: {}", path, mesh.status().message()));
  }
  w.mesh = *mesh;
  // One palette per 1/30 s of the clip; frame f % size wraps around its duration.
  const auto count =
      static_cast<int>(std::clamp(std::ceil(clip->duration * kGltfWorkloadFps), 1.0, 3600.0));
  for (int f = 0; f < count; ++f) {
    auto palettes =
        MeshPalettes(*character, SampleClip(*character, *clip, f / kGltfWorkloadFps), *meshes);
    if (!palettes.ok()) return palettes.status();
    std::vector<float> palette;
    for (const std::vector<float>& p : *palettes) palette.insert(palette.end(), p.begin(), p.end());
    w.palettes.push_back(std::move(palette));
  }
  return w;
}

}  // namespace skinserve::load
