#include "skinserve/character/character_mesh.h"

#include <fmt/format.h>

#include <algorithm>
#include <limits>
#include <map>
#include <tuple>
#include <utility>

namespace skinserve {
namespace {

// `count` deltas of `part` (empty: zeros) appended to `all`.
void AppendDeltas(const std::vector<float>& part, std::size_t count, std::vector<float>* all) {
  if (part.empty()) {
    all->resize(all->size() + 3 * count, 0.0f);
  } else {
    all->insert(all->end(), part.begin(), part.end());
  }
}

// Appends `p`'s morph targets to `mesh`'s, renumbered to start at vertex `first`; with
// `morph_normals` (`morph_tangents`), normal (tangent) deltas too (zeros where `p` has none).
void AppendMorphTargets(const SkinnedPrimitive& p, uint32_t first, bool morph_normals,
                        bool morph_tangents, CharacterMesh* mesh) {
  MeshArrays& a = mesh->arrays;
  const MeshArrays& pa = p.arrays;
  for (std::size_t t = 0; t < pa.morph_target_sizes.size(); ++t) {
    a.morph_target_sizes.push_back(pa.morph_target_sizes[t]);
    mesh->morph_sources.push_back({.node = p.node, .target = static_cast<uint32_t>(t)});
  }
  for (uint32_t v : pa.morph_indices) a.morph_indices.push_back(first + v);
  a.morph_position_deltas.insert(a.morph_position_deltas.end(), pa.morph_position_deltas.begin(),
                                 pa.morph_position_deltas.end());
  if (morph_normals) {
    AppendDeltas(pa.morph_normal_deltas, pa.morph_indices.size(), &a.morph_normal_deltas);
  }
  if (morph_tangents) {
    AppendDeltas(pa.morph_tangent_deltas, pa.morph_indices.size(), &a.morph_tangent_deltas);
  }
}

// Appends `p` to `mesh`, padding its influences to the mesh's. A rigid part's vertices get
// joint `rigid_joint` (its node's palette entry), weight 1.
void Append(const SkinnedPrimitive& p, int index, uint16_t rigid_joint, bool morph_normals,
            bool morph_tangents, CharacterMesh* mesh) {
  MeshArrays& a = mesh->arrays;
  const uint32_t first = a.vertex_count;
  const uint32_t b = a.influences;
  const uint32_t pb = p.arrays.influences;
  a.positions.insert(a.positions.end(), p.arrays.positions.begin(), p.arrays.positions.end());
  a.normals.insert(a.normals.end(), p.arrays.normals.begin(), p.arrays.normals.end());
  a.tangents.insert(a.tangents.end(), p.arrays.tangents.begin(), p.arrays.tangents.end());
  for (uint32_t v = 0; v < p.arrays.vertex_count; ++v) {
    for (uint32_t i = 0; i < b; ++i) {
      const bool real = i < pb;
      // Padding reads nothing of the part (its arrays hold pb influences a vertex).
      const uint16_t joint = !real       ? 0
                             : p.rigid() ? rigid_joint
                                         : p.arrays.joints[std::size_t{v} * pb + i];
      a.joints.push_back(joint);
      a.weights.push_back(real ? p.arrays.weights[std::size_t{v} * pb + i] : 0.0f);
    }
  }
  AppendMorphTargets(p, first, morph_normals, morph_tangents, mesh);
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

std::size_t SkinJoints(const Character& character, int skin) {
  if (skin < 0 || static_cast<std::size_t>(skin) >= character.skins.size()) return 0;
  return character.skins[static_cast<std::size_t>(skin)].joints.size();
}

// Which primitives go together: same skin, same presence of normals and of tangents
// (tangents come only with normals); meshes in order of their first primitive.
using MeshKey = std::tuple<int, bool, bool>;  // skin, normals, tangents
struct MeshGroups {
  std::vector<MeshKey> keys;  // in order of their first primitive
  std::map<MeshKey, std::vector<int>> members;
  bool has(int skin, bool normals, bool tangents) const {
    return members.count({skin, normals, tangents}) > 0;
  }
};

MeshGroups GroupPrimitives(const std::vector<SkinnedPrimitive>& primitives, int only) {
  auto taken = [&](std::size_t i) { return only < 0 || static_cast<std::size_t>(only) == i; };
  // Rigid parts go with the first skin taken (-1: none).
  int rigid_skin = -1;
  for (std::size_t i = 0; i < primitives.size() && rigid_skin < 0; ++i) {
    if (taken(i) && !primitives[i].rigid()) rigid_skin = primitives[i].skin;
  }
  MeshGroups groups;
  for (std::size_t i = 0; i < primitives.size(); ++i) {
    if (!taken(i)) continue;
    const int skin = primitives[i].rigid() ? rigid_skin : primitives[i].skin;
    const MeshKey key{skin, !primitives[i].arrays.normals.empty(),
                      !primitives[i].arrays.tangents.empty()};
    if (groups.members.find(key) == groups.members.end()) groups.keys.push_back(key);
    groups.members[key].push_back(static_cast<int>(i));
  }
  return groups;
}

// The skin's name (or "skins[i]", or "rigid parts"); the skin's parts split on normals:
// "(normals)" / "(no normals)"; those with normals split on tangents too: "(tangents)" /
// "(no tangents)".
std::string MeshName(const Character& character, const MeshKey& key, const MeshGroups& groups) {
  const auto [skin, normals, tangents] = key;
  std::string name;
  if (skin < 0) {
    name = "rigid parts";
  } else if (static_cast<std::size_t>(skin) < character.skins.size() &&
             !character.skins[static_cast<std::size_t>(skin)].name.empty()) {
    name = character.skins[static_cast<std::size_t>(skin)].name;
  } else {
    name = fmt::format("skins[{}]", skin);
  }
  if (groups.has(skin, !normals, false) || groups.has(skin, !normals, true)) {
    name += normals ? " (normals)" : " (no normals)";
  }
  if (normals && groups.has(skin, true, !tangents)) {
    name += tangents ? " (tangents)" : " (no tangents)";
  }
  return name;
}

// One mesh of `members`, the primitives of one group: their vertices, joints (the skin's,
// then one per rigid part's node) and morph targets, within a mesh's limits.
Result<CharacterMesh> BuildMesh(const Character& character, const std::vector<int>& members,
                                int skin, std::string name) {
  const auto& primitives = character.primitives;
  CharacterMesh mesh;
  mesh.skin = skin;
  mesh.name = std::move(name);
  uint64_t vertices = 0;
  // A mesh's targets move normals (tangents) for all or none of them.
  bool morph_normals = false, morph_tangents = false;
  for (int i : members) {
    const SkinnedPrimitive& p = primitives[static_cast<std::size_t>(i)];
    vertices += p.arrays.vertex_count;
    morph_normals |= !p.arrays.morph_normal_deltas.empty();
    morph_tangents |= !p.arrays.morph_tangent_deltas.empty();
    mesh.arrays.influences = std::max(mesh.arrays.influences, p.arrays.influences);
    if (p.rigid() && std::find(mesh.rigid_nodes.begin(), mesh.rigid_nodes.end(), p.node) ==
                         mesh.rigid_nodes.end()) {
      mesh.rigid_nodes.push_back(p.node);
    }
  }
  if (vertices > std::numeric_limits<uint32_t>::max()) {
    return InvalidArgument(
        fmt::format("{}: its primitives hold {} vertices; a mesh holds at "
                    "most {}",
                    mesh.name, vertices, std::numeric_limits<uint32_t>::max()));
  }
  const std::size_t skin_joints = SkinJoints(character, mesh.skin);
  const std::size_t joints = skin_joints + mesh.rigid_nodes.size();
  if (joints > kMaxJointsLimit) {
    return InvalidArgument(fmt::format(
        "{}: its skin's {} joints and {} rigid part nodes make {} palette entries; at most {}",
        mesh.name, skin_joints, mesh.rigid_nodes.size(), joints, kMaxJointsLimit));
  }
  mesh.arrays.joint_count = static_cast<uint32_t>(joints);
  for (int i : members) {
    const SkinnedPrimitive& p = primitives[static_cast<std::size_t>(i)];
    const auto place = static_cast<std::size_t>(
        std::find(mesh.rigid_nodes.begin(), mesh.rigid_nodes.end(), p.node) -
        mesh.rigid_nodes.begin());
    Append(p, i, static_cast<uint16_t>(skin_joints + place), morph_normals, morph_tangents, &mesh);
  }
  return mesh;
}

}  // namespace

Result<std::vector<CharacterMesh>> CharacterMeshes(const Character& character, int only) {
  const auto& primitives = character.primitives;
  if (only >= 0 && static_cast<std::size_t>(only) >= primitives.size()) {
    return InvalidArgument(
        fmt::format("primitive {} is not below the {} primitive(s)", only, primitives.size()));
  }
  const MeshGroups groups = GroupPrimitives(primitives, only);
  std::vector<CharacterMesh> meshes;
  for (const MeshKey& key : groups.keys) {
    auto mesh = BuildMesh(character, groups.members.at(key), std::get<0>(key),
                          MeshName(character, key, groups));
    if (!mesh.ok()) return mesh.status();
    meshes.push_back(std::move(mesh).value());
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

Result<std::vector<float>> MeshPalette(const Character& character, const Pose& pose,
                                       const CharacterMesh& mesh) {
  std::vector<float> palette;
  if (mesh.skin >= 0) {
    auto skin = SkinPalette(character, pose, mesh.skin);
    if (!skin.ok()) return skin.status();
    palette = std::move(*skin);
  }
  if (!mesh.rigid_nodes.empty()) {
    auto nodes = NodePalette(character, pose, mesh.rigid_nodes);
    if (!nodes.ok()) return nodes.status();
    palette.insert(palette.end(), nodes->begin(), nodes->end());
  }
  return palette;
}

Result<std::vector<std::vector<float>>> MeshPalettes(const Character& character, const Pose& pose,
                                                     const std::vector<CharacterMesh>& meshes) {
  std::vector<std::vector<float>> palettes;
  palettes.reserve(meshes.size());
  for (const CharacterMesh& mesh : meshes) {
    auto palette = MeshPalette(character, pose, mesh);
    if (!palette.ok()) return palette.status();
    palettes.push_back(std::move(*palette));
  }
  return palettes;
}

}  // namespace skinserve
