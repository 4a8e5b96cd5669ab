#include "character_input.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>

#include "skinserve/character/gltf_import.h"

namespace skinserve::cli {

bool IsGltfPath(const std::string& path) {
  std::string lower = path;
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return lower.ends_with(".glb") || lower.ends_with(".gltf");
}

Result<Character> ImportCharacter(const std::string& path) {
  auto character = LoadGltfFile(path);
  // The importer names the file itself in most errors: never twice.
  if (!character.ok() && !character.status().message().starts_with(path + ":")) {
    return Status(character.status().code(),
                  fmt::format("{}: {}", path, character.status().message()));
  }
  if (character.ok()) PrintImportWarnings(*character, path);
  return character;
}

Result<const SkinnedPrimitive*> PickPrimitive(const Character& character, int index,
                                              const std::string& path) {
  if (index < 0 || static_cast<std::size_t>(index) >= character.primitives.size()) {
    return InvalidArgument(
        fmt::format("--primitive {} is not below the {} primitive(s) (skinned and rigid) of {}",
                    index, character.primitives.size(), path));
  }
  return &character.primitives[static_cast<std::size_t>(index)];
}

Result<const AnimationClip*> PickClip(const Character& character, const std::string& name,
                                      const std::string& path) {
  if (const AnimationClip* clip = character.FindClip(name)) return clip;
  if (character.clips.empty()) {
    return InvalidArgument(fmt::format("{} has no animation clip", path));
  }
  std::string names;
  for (const AnimationClip& clip : character.clips) {
    names += (names.empty() ? "'" : ", '") + clip.name + "'";
  }
  return InvalidArgument(
      fmt::format("--clip '{}': {} has no such clip; it has {}", name, path, names));
}

}  // namespace skinserve::cli
