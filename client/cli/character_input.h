// glTF characters as input to skinserve-cli's commands: import with the file's name in
// every error, and the primitive and clip a command asks for, or an error listing what
// the file has.
#pragma once

#include <string>

#include "skinserve/character/character.h"
#include "skinserve/model/status.h"

namespace skinserve::cli {

// True for a .glb or .gltf name (any case).
bool IsGltfPath(const std::string& path);

// LoadGltfFile, with `path` in front of its error (once).
Result<Character> ImportCharacter(const std::string& path);

// primitives[index], or INVALID_ARGUMENT "--primitive 3 is not below the 1
// primitive(s) of FILE".
Result<const SkinnedPrimitive*> PickPrimitive(const Character& character, int index,
                                              const std::string& path);

// The clip named `name` (the first when empty), or INVALID_ARGUMENT listing the file's clips.
Result<const AnimationClip*> PickClip(const Character& character, const std::string& name,
                                      const std::string& path);

}  // namespace skinserve::cli
