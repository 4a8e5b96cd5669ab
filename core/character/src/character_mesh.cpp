#include "skinserve/character/character_mesh.h"

#include <fmt/format.h>

#include <algorithm>
#include <limits>
#include <map>
#include <utility>

namespace skinserve {
namespace {

// Appends `p`'s morph targets to `mesh`'s, renumbered to start at vertex `first`; with
// `morph_normals`, normal deltas too (zeros where `p` has none).
void AppendMorphTargets(const SkinnedPrimitive& p, uint32_t first, bool morph_normals,
                        CharacterMesh* mesh) {
  MeshArrays& a = mesh->arrays;
  const MeshArrays& pa = p.arrays;
  for (std::size_t t = 0; t < pa.morph_target_sizes.size(); ++t) {
    a.morph_target_sizes.push_back(pa.morph_target_sizes[t]);
    mesh->morph_sources.push_back({.node = p.node, .target = static_cast<uint32_t>(t)});
  }
  for (uint32_t v : pa.morph_indices) a.morph_indices.push_back(first + v);
  a.morph_position_deltas.insert(a.morph_position_deltas.end(), pa.morph_position_deltas.begin(),
                                 pa.morph_position_deltas.end());
  if (!morph_normals) return;
  if (pa.morph_normal_deltas.empty()) {
    a.morph_normal_deltas.resize(a.morph_normal_deltas.size() + 3 * pa.morph_indices.size(), 0.0f);
  } else {
    a.morph_normal_deltas.insert(a.morph_normal_deltas.end(), pa.morph_normal_deltas.begin(),
                                 pa.morph_normal_deltas.end());
  }
}

// Appends `p` to `mesh`, padding its influences to the mesh's.
void Append(const SkinnedPrimitive& p, int index, bool morph_normals, CharacterMesh* mesh) {
  MeshArrays& a = mesh->arrays;
  const uint32_t first = a.vertex_count;
  const uint32_t b = a.influences;
  const uint32_t pb = p.arrays.influences;
  a.positions.insert(a.positions.end(), p.arrays.positions.begin(), p.arrays.positions.end());
  a.normals.insert(a.normals.end(), p.arrays.normals.begin(), p.arrays.normals.end());
  for (uint32_t v = 0; v < p.arrays.vertex_count; ++v) {
    for (uint32_t i = 0; i < b; ++i) {
      const bool real = i < pb;
      a.joints.push_back(real ? p.arrays.joints[std::size_t{v} * pb + i] : 0);
      a.weights.push_back(real ? p.arrays.weights[std::size_t{v} * pb + i] : 0.0f);
    }
  }
  AppendMorphTargets(p, first, morph_normals, mesh);
  a.vertex_count += p.arrays.vertex_count;
  const std::size_t first_index = mesh->indices.size();
  for (uint32_t i : p.indices) mesh->indices.push_back(first + i);
  mesh->parts.push_back({.primitive = index,
                         .name = p.name,
                         .first_vertex = first,
                         .vertex_count = p.arrays.vertex_count,
                         .first_index = first_index,
                         .index_count = p.indices.size()});
}

}  // namespace

Result<std::vector<CharacterMesh>> CharacterMeshes(const Character& character, int only) {
  const auto& primitives = character.primitives;
  if (only >= 0 && static_cast<std::size_t>(only) >= primitives.size()) {
    return InvalidArgument(fmt::format("primitive {} is not below the {} skinned primitive(s)",
                                       only, primitives.size()));
  }
  // Which primitives go together: same skin, same presence of normals; meshes in order of
  // their first primitive.
  std::vector<std::pair<int, bool>> keys;
  std::map<std::pair<int, bool>, std::vector<int>> groups;
  bool split_on_normals = false;
  for (std::size_t i = 0; i < primitives.size(); ++i) {
    if (only >= 0 && static_cast<std::size_t>(only) != i) continue;
    const std::pair<int, bool> key{primitives[i].skin, !primitives[i].arrays.normals.empty()};
    if (groups.find(key) == groups.end()) keys.push_back(key);
    groups[key].push_back(static_cast<int>(i));
    split_on_normals |= groups.count({key.first, !key.second}) > 0;
  }

  std::vector<CharacterMesh> meshes;
  for (const auto& key : keys) {
    const std::vector<int>& members = groups[key];
    CharacterMesh mesh;
    mesh.skin = key.first;
    const std::string skin_name =
        mesh.skin >= 0 && static_cast<std::size_t>(mesh.skin) < character.skins.size() &&
                !character.skins[static_cast<std::size_t>(mesh.skin)].name.empty()
            ? character.skins[static_cast<std::size_t>(mesh.skin)].name
            : fmt::format("skins[{}]", mesh.skin);
    mesh.name = skin_name;
    if (split_on_normals && groups.count({key.first, !key.second}) > 0) {
      mesh.name += key.second ? " (normals)" : " (no normals)";
    }
    uint64_t vertices = 0;
    bool morph_normals = false;  // a mesh's targets move normals for all or none of them
    for (int i : members) {
      const MeshArrays& a = primitives[static_cast<std::size_t>(i)].arrays;
      vertices += a.vertex_count;
      morph_normals |= !a.morph_normal_deltas.empty();
      mesh.arrays.influences = std::max(mesh.arrays.influences, a.influences);
      mesh.arrays.joint_count = std::max(mesh.arrays.joint_count, a.joint_count);
    }
    if (vertices > std::numeric_limits<uint32_t>::max()) {
      return InvalidArgument(
          fmt::format("{}: its primitives hold {} vertices; a mesh holds at "
                      "most {}",
                      mesh.name, vertices, std::numeric_limits<uint32_t>::max()));
    }
    for (int i : members) {
      Append(primitives[static_cast<std::size_t>(i)], i, morph_normals, &mesh);
    }
    meshes.push_back(std::move(mesh));
  }
  return meshes;
}

void MeshMorphWeights(const CharacterMesh& mesh, const Pose& pose, std::vector<MorphWeight>* out) {
  out->clear();
  for (std::size_t t = 0; t < mesh.morph_sources.size(); ++t) {
    const MorphTargetSource& source = mesh.morph_sources[t];
    if (source.node < 0 || static_cast<std::size_t>(source.node) >= pose.size()) continue;
    const std::vector<float>& weights = pose[static_cast<std::size_t>(source.node)].weights;
    if (source.target >= weights.size() || weights[source.target] == 0.0f) continue;
    out->push_back({static_cast<uint32_t>(t), weights[source.target]});
  }
}

Result<std::vector<std::vector<float>>> MeshPalettes(const Character& character, const Pose& pose,
                                                     const std::vector<CharacterMesh>& meshes) {
  std::map<int, std::vector<float>> by_skin;
  std::vector<std::vector<float>> palettes;
  palettes.reserve(meshes.size());
  for (const CharacterMesh& mesh : meshes) {
    auto known = by_skin.find(mesh.skin);
    if (known == by_skin.end()) {
      auto palette = SkinPalette(character, pose, mesh.skin);
      if (!palette.ok()) return palette.status();
      known = by_skin.emplace(mesh.skin, std::move(*palette)).first;
    }
    palettes.push_back(known->second);
  }
  return palettes;
}

}  // namespace skinserve
