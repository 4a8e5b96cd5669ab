// Character: a character (skinned meshes and rigid parts) imported from glTF 2.0 — the paper's
// stage 1 (parse the character) — and the data its stage 2 (joint matrices per frame) needs. Plain
// data; the importer (gltf_import.h) fills it, animation.h samples it, Mesh::Create validates the
// primitives' arrays before anything is skinned.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <glm/gtc/quaternion.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include "skinserve/model/mesh.h"

namespace skinserve {

// A scene node's local transform, as the file states it (TRS, or a matrix decomposed to
// TRS at import). Animation channels replace its translation, rotation or scale.
struct CharacterNode {
  std::string name;
  int parent = -1;  // index into Character::nodes, -1 for a root
  glm::vec3 translation{0.0f};
  glm::quat rotation{1.0f, 0.0f, 0.0f, 0.0f};  // w, x, y, z
  glm::vec3 scale{1.0f};
  // The morph target weights of the node's mesh: the node's `weights`, else the mesh's,
  // else zeros, one per target; empty when its mesh has no targets. `weights` channels
  // replace them.
  std::vector<float> weights;
};

// A glTF skin: its joints are nodes; palette[j] = model(joints[j]) * inverse_bind[j].
struct CharacterSkin {
  std::string name;
  std::vector<int> joints;              // node index per joint (the palette's order)
  std::vector<glm::mat4> inverse_bind;  // one per joint (identity when the file omits them)
};

// How the file stored one vertex attribute: its glTF componentType (KHR_mesh_quantization
// allows integers besides FLOAT) and `normalized` flag. kNone: no such attribute.
enum class StoredType : uint8_t { kNone, kFloat, kByte, kUnsignedByte, kShort, kUnsignedShort };
std::string_view StoredTypeName(StoredType type);  // glTF's: "FLOAT", "UNSIGNED_SHORT", ...

struct StoredAttribute {
  StoredType type = StoredType::kNone;
  bool normalized = false;
};

// A primitive's attributes as the file stored them (the arrays hold their float values),
// for tools that match an upload to the file (rest_encoding_choice.h). weights: the widest
// of the WEIGHTS_n sets (FLOAT over UNSIGNED_SHORT over UNSIGNED_BYTE); none on a rigid part.
struct StoredAttributes {
  StoredAttribute position;
  StoredAttribute normal;
  StoredAttribute weights;
};

// One primitive of one mesh node, ready for Mesh::Create: skinned (the node has a skin) or
// a rigid part (skin -1: a mesh node without a skin, whose vertices all follow the node).
//  - arrays: positions, normals (when present), tangents (TANGENT, when present with
//    NORMAL: xyz renormalised, w snapped to +-1), joints/weights with `influences` = 4 per
//    JOINTS_n/WEIGHTS_n set present (4 or 8), joint indices into the skin's joints; a
//    rigid part has 1 influence, joint 0 weight 1, joint_count 1 (palette: the node's
//    world matrix), and its positions in the node's space.
//    Morph targets (the primitive's `targets`: POSITION, NORMAL and TANGENT deltas, the
//    last two when the primitive has normals, tangents) as sparse targets, in the file's
//    order: a vertex whose deltas are all zero is left out. Target t takes weight t of
//    `node` (CharacterNode::weights).
//  - indices: triangle list into the vertices (3 per triangle), for viewers and renders.
struct SkinnedPrimitive {
  std::string name;  // "<mesh name>/<primitive index>"
  int node = -1;     // the mesh node that instantiates it
  int skin = -1;     // index into Character::skins; -1: a rigid part following `node`
  bool rigid() const { return skin < 0; }
  MeshArrays arrays;
  StoredAttributes stored;  // how the file stored POSITION, NORMAL and WEIGHTS_n
  std::vector<uint32_t> indices;
  // What of the primitive the spec says to ignore and the importer left out (e.g. TANGENT
  // without NORMAL), one line each, naming the object: the tools print them.
  std::vector<std::string> warnings;
};

enum class ChannelPath { kTranslation, kRotation, kScale, kWeights };
enum class Interpolation { kLinear, kStep, kCubicSpline };

// One animation channel with its sampler's data, as in the file.
//  - times: strictly increasing keyframe times in seconds.
//  - values: per key 3 (translation, scale), 4 (rotation x y z w) or, for weights, one per
//    morph target of the node's mesh floats; CUBICSPLINE keys hold in-tangent, value,
//    out-tangent (3 times as many floats).
struct AnimationChannel {
  int node = -1;
  ChannelPath path = ChannelPath::kTranslation;
  Interpolation interpolation = Interpolation::kLinear;
  std::vector<float> times;
  std::vector<float> values;
};

struct AnimationClip {
  std::string name;
  float duration = 0.0f;  // the last key time of any channel
  std::vector<AnimationChannel> channels;
};

struct Character {
  std::vector<CharacterNode> nodes;
  std::vector<CharacterSkin> skins;
  std::vector<SkinnedPrimitive> primitives;
  std::vector<AnimationClip> clips;

  // The clip named `name` (the first when `name` is empty); nullptr when there is none.
  const AnimationClip* FindClip(const std::string& name) const;
};

}  // namespace skinserve
