#include "workload.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "skinserve/core/character/animation.h"
#include "skinserve/core/character/gltf_import.h"
#include "skinserve/core/synthetic.h"

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

Result<Workload> MakeGltfWorkload(const std::string& path, int primitive, bool normals) {
  auto character = LoadGltfFile(path);
  if (!character.ok()) {
    // The importer names the file itself in most errors: never twice.
    if (character.status().message().starts_with(path + ":")) return character.status();
    return Status(character.status().code(),
                  fmt::format("{}: {}", path, character.status().message()));
  }
  if (primitive < 0 || static_cast<std::size_t>(primitive) >= character->primitives.size()) {
    return InvalidArgument(
        fmt::format("--primitive {} is not below the {} skinned primitive(s) of {}", primitive,
                    character->primitives.size(), path));
  }
  const SkinnedPrimitive& p = character->primitives[static_cast<std::size_t>(primitive)];
  if (normals && p.arrays.normals.empty()) {
    return InvalidArgument(fmt::format("--normals: {} has no normals in {}", p.name, path));
  }
  const AnimationClip* clip = character->FindClip("");
  if (clip == nullptr) return InvalidArgument(fmt::format("{} has no animation clip", path));

  Workload w;
  w.vertices = p.arrays.vertex_count;
  w.bones = p.arrays.influences;
  w.joints = p.arrays.joint_count;
  w.normals = normals;
  w.arrays = std::make_shared<const MeshArrays>(p.arrays);
  auto mesh = Mesh::Create(*w.arrays);
  if (!mesh.ok()) {
    return Status(mesh.status().code(), fmt::format("{}: {}", p.name, mesh.status().message()));
  }
  w.mesh = *mesh;
  // One palette per 1/30 s of the clip; frame f % size wraps around its duration.
  const auto count =
      static_cast<int>(std::clamp(std::ceil(clip->duration * kGltfWorkloadFps), 1.0, 3600.0));
  for (int f = 0; f < count; ++f) {
    auto palette =
        SkinPalette(*character, SampleClip(*character, *clip, f / kGltfWorkloadFps), p.skin);
    if (!palette.ok()) return palette.status();
    w.palettes.push_back(std::move(*palette));
  }
  return w;
}

}  // namespace skinserve::load
