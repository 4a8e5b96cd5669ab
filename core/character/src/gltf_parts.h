// The importer's stages, each turning one part of a loaded tinygltf::Model into Character
// data. Each checks what it reads and names the object in its errors; they run in this
// order because primitives need the skins and clips need the nodes.
#pragma once

#include <tiny_gltf.h>

#include <vector>

#include "skinserve/character/character.h"
#include "skinserve/model/status.h"

namespace skinserve::gltf {

// Every node's local TRS (matrices decomposed) and parent; rejects a child with two
// parents and cycles.
Result<std::vector<CharacterNode>> ImportNodes(const tinygltf::Model& model);

// Every skin: joints (valid node indices) and inverse bind matrices (identity when absent).
Result<std::vector<CharacterSkin>> ImportSkins(const tinygltf::Model& model);

// Every primitive of every node with a mesh: skinned when the node has a skin (the
// primitives with JOINTS_0/WEIGHTS_0), else a rigid part following the node (skin -1, one
// influence: joint 0, weight 1).
Result<std::vector<SkinnedPrimitive>> ImportSkinnedPrimitives(
    const tinygltf::Model& model, const std::vector<CharacterSkin>& skins);

// Every animation's translation, rotation and scale channels (weights channels are not
// part of skinning and are left out).
Result<std::vector<AnimationClip>> ImportClips(const tinygltf::Model& model);

}  // namespace skinserve::gltf
