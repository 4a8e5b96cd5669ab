#include "gltf_pose_workload.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <exception>
#include <fstream>
#include <iterator>
#include <vector>

#include "skinserve/character/character_mesh.h"
#include "skinserve/character/gltf_import.h"
#include "skinserve/character/rig.h"

namespace skinserve::load {
bool IsGlbPath(const std::string& path) {
  if (path.size() < 4) return false;
  std::string end = path.substr(path.size() - 4);
  std::transform(end.begin(), end.end(), end.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  return end == ".glb";
}

namespace {

// What the float64 check covers: the whole character one skinned primitive of skin 0, with
// no rigid parts and no morph targets.
Status CheckOneSkinnedPrimitive(const std::vector<CharacterMesh>& meshes, const std::string& path) {
  const std::string scope =
      "the float64 check reads one skinned primitive of skin 0 without morph targets";
  if (meshes.size() != 1 || meshes.front().parts.size() != 1) {
    std::size_t parts = 0;
    for (const CharacterMesh& m : meshes) parts += m.parts.size();
    return InvalidArgument(
        fmt::format("--animate {}: {}; the file has {} mesh(es) of {} "
                    "primitive(s) together",
                    path, scope, meshes.size(), parts));
  }
  const CharacterMesh& mesh = meshes.front();
  if (mesh.skin != 0 || !mesh.rigid_nodes.empty()) {
    return InvalidArgument(fmt::format("--animate {}: {}; its primitive is {}", path, scope,
                                       mesh.skin < 0 ? "rigid" : "of another skin"));
  }
  if (!mesh.morph_sources.empty()) {
    return InvalidArgument(fmt::format("--animate {}: {}; its primitive has {} morph targets", path,
                                       scope, mesh.morph_sources.size()));
  }
  return Status::Ok();
}

// The clip `name` names: an index into the file's clips when it is all digits, else a clip
// name; the first when empty. Its index, or INVALID_ARGUMENT listing the file's clips.
Result<std::size_t> PickClipIndex(const Character& character, const std::string& name,
                                  const std::string& path) {
  if (character.clips.empty())
    return InvalidArgument(fmt::format("{} has no animation clip", path));
  if (name.empty()) return std::size_t{0};
  const bool index = name.size() <= 6 && name.find_first_not_of("0123456789") == std::string::npos;
  if (index && std::stoul(name) < character.clips.size()) return std::size_t{std::stoul(name)};
  for (std::size_t i = 0; !index && i < character.clips.size(); ++i) {
    if (character.clips[i].name == name) return i;
  }
  std::string names;
  for (std::size_t i = 0; i < character.clips.size(); ++i) {
    names += fmt::format("{}{} '{}'", i == 0 ? "" : ", ", i, character.clips[i].name);
  }
  return InvalidArgument(
      fmt::format("--clip '{}': {} has no such clip; it has {}", name, path, names));
}

// The check's own reading of the file, or INVALID_ARGUMENT naming what it could not read.
Result<gltf_reference::RefCharacter> ReadCheckReference(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  const std::vector<uint8_t> bytes{std::istreambuf_iterator<char>(in),
                                   std::istreambuf_iterator<char>()};
  try {
    return gltf_reference::ReadReference(gltf_reference::ParseGlb(bytes));
  } catch (const std::exception& e) {
    return InvalidArgument(
        fmt::format("--animate {}: the float64 check cannot read it: {}", path, e.what()));
  }
}

// The importer's reading and the check's must describe one primitive and one clip.
Status CheckSameCharacter(const gltf_reference::RefCharacter& ref, const CharacterMesh& mesh,
                          const Rig& rig, const Character& character, std::size_t clip,
                          const std::string& path) {
  if (ref.primitive.vertex_count != mesh.arrays.vertex_count ||
      ref.joints.size() != rig.skeleton.palette_size() ||
      ref.clips.size() != character.clips.size() ||
      ref.clips[clip].name != character.clips[clip].name) {
    return Internal(fmt::format(
        "--animate {}: the float64 check reads {} vertices, {} joints and {} clips; the importer "
        "{}, {} and {}",
        path, ref.primitive.vertex_count, ref.joints.size(), ref.clips.size(),
        mesh.arrays.vertex_count, rig.skeleton.palette_size(), character.clips.size()));
  }
  if (!(ref.clips[clip].duration > 0)) {
    return InvalidArgument(
        fmt::format("--animate {}: clip '{}' moves no joint (no translation, "
                    "rotation or scale channel after its first key)",
                    path, ref.clips[clip].name));
  }
  return Status::Ok();
}

}  // namespace

Result<std::shared_ptr<PoseWorkload>> MakeGltfPoseWorkload(const std::string& path,
                                                           const std::string& clip) {
  if (!IsGlbPath(path)) {
    return InvalidArgument(fmt::format(
        "--animate {}: 'synthetic' or a binary glTF file (.glb, which the float64 check reads)",
        path));
  }
  auto character = LoadGltfFile(path);
  if (!character.ok()) {
    if (character.status().message().starts_with(path + ":")) return character.status();
    return Status(character.status().code(),
                  fmt::format("{}: {}", path, character.status().message()));
  }
  auto meshes = CharacterMeshes(*character);
  if (!meshes.ok()) return meshes.status();
  if (Status s = CheckOneSkinnedPrimitive(*meshes, path); !s.ok()) return s;
  auto index = PickClipIndex(*character, clip, path);
  if (!index.ok()) return index.status();
  const CharacterMesh& mesh = meshes->front();
  auto rig = RigFromMesh(*character, mesh);
  if (!rig.ok()) {
    return Status(rig.status().code(), fmt::format("{}: {}", path, rig.status().message()));
  }
  auto ref = ReadCheckReference(path);
  if (!ref.ok()) return ref.status();
  if (Status s = CheckSameCharacter(*ref, mesh, *rig, *character, *index, path); !s.ok()) return s;
  auto pose = std::make_shared<PoseWorkload>();
  bool weights_on_server = false;  // no morph targets: the clip keeps no weights track
  pose->clip = RawClipForMesh(character->clips[*index], *rig, mesh, &weights_on_server);
  pose->skeleton = std::move(rig->skeleton);
  pose->label = character->clips[*index].name;
  pose->duration = ref->clips[*index].duration;
  SetLap(pose.get());
  pose->gltf =
      std::make_shared<const GltfPoseReference>(GltfPoseReference{std::move(*ref), *index});
  return pose;
}

}  // namespace skinserve::load
