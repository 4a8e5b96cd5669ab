// glTF 2.0 import (.glb, or .gltf with its .bin buffers) into a Character, with tinygltf.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "skinserve/character/character.h"
#include "skinserve/model/status.h"

namespace skinserve {

// Reads every primitive of every mesh node (skinned with the node's skin, or a rigid part
// following a node without one), the node hierarchy, the skins and the clips. Sparse
// accessors and KHR_mesh_quantization's integer attributes are read. Files that break the spec
// (truncated GLB, accessor out of its buffer view, joint index past the skin, a component type the
// spec does not allow for an attribute, a missing skin or inverse-bind count mismatch) give
// INVALID_ARGUMENT naming the object, e.g. "meshes[0].primitives[0].attributes.JOINTS_0: accessor 5
// reads past bufferView 2". A file with no primitive to skin is INVALID_ARGUMENT too.
Result<Character> LoadGltfFile(const std::string& path);

// The same for bytes in memory: a GLB, or glTF JSON whose buffers are data: URIs or files
// relative to `base_dir`.
Result<Character> LoadGltfBytes(std::span<const uint8_t> bytes, const std::string& base_dir = "");

// Writes each primitive's warnings (SkinnedPrimitive::warnings: what the importer left out
// as the spec says) to stderr as "<path>: warning: ...", for the command-line tools.
void PrintImportWarnings(const Character& character, const std::string& path);

}  // namespace skinserve
