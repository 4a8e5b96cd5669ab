// A whole character as the server needs it: its skinned primitives grouped by skin, each
// group one mesh (the primitives' vertices one after another), with its rigid parts. A skin's
// primitives share one palette per frame, so a group travels as one upload and one stream, however
// many pieces the file split the character into.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "skinserve/character/animation.h"
#include "skinserve/character/character.h"
#include "skinserve/model/status.h"

namespace skinserve {

// Where one primitive lies inside its CharacterMesh.
struct PrimitiveSpan {
  int primitive = -1;  // index into Character::primitives
  std::string name;    // the primitive's, e.g. "Body/0"
  uint32_t first_vertex = 0;
  uint32_t vertex_count = 0;
  std::size_t first_index = 0;  // into CharacterMesh::indices
  std::size_t index_count = 0;
};

// Where one of a CharacterMesh's morph targets takes its weight: weight `target` of node
// `node` (CharacterNode::weights of the pose).
struct MorphTargetSource {
  int node = -1;
  uint32_t target = 0;
};

// Primitives of one skin, and the character's rigid parts, concatenated.
//  - arrays: positions, normals and tangents (all or none of the parts have each; morph
//    normal and tangent deltas zero for a part whose targets lack them), joints/weights padded
//    to the largest influence count of the parts (weight 0, joint 0), joint_count = the
//    skin's joints + rigid_nodes.
//  - palette (MeshPalette): the skin's palette, then the world matrix of each rigid node;
//    a rigid part's vertices all have joint = the skin's joint count + its node's place in
//    rigid_nodes, weight 1.
//  - indices: every part's triangles, renumbered into the concatenated vertices.
//  - morph_sources: one per morph target of `arrays` (every part's targets, part after
//    part, their vertices renumbered), naming the node weight that drives it.
struct CharacterMesh {
  int skin = -1;     // -1: no skin (rigid parts only)
  std::string name;  // the skin's name, or "skins[N]", or "rigid parts"; with " (normals)" /
                     // " (no normals)", " (tangents)" / " (no tangents)" when the parts
                     // are split on that
  std::vector<int> rigid_nodes;  // nodes the rigid parts follow, in order of first part
  MeshArrays arrays;
  std::vector<uint32_t> indices;
  std::vector<PrimitiveSpan> parts;  // in the file's order
  std::vector<MorphTargetSource> morph_sources;
};

// The character's meshes: one per skin, in order of the skins' first primitive. Rigid
// parts join the mesh of the first skin (so a character with one skin is one mesh, one
// palette, one request), or a mesh of their own (skin -1) when no skinned primitive is
// taken. Parts that disagree on normals (or tangents) go into two meshes (with, without),
// since a mesh has normals (tangents) for all of its vertices or none. `only` >= 0 takes that
// primitive alone. INVALID_ARGUMENT when `only` is not a primitive, a mesh's parts exceed 2^32 - 1
// vertices, or its skin's joints and rigid nodes exceed kMaxJointsLimit.
Result<std::vector<CharacterMesh>> CharacterMeshes(const Character& character, int only = -1);

// The mesh's non-zero morph target weights at `pose` (sparse, as a frame carries them),
// into `out` (its capacity reused).
void MeshMorphWeights(const CharacterMesh& mesh, const Pose& pose, std::vector<MorphWeight>* out);

// The palette of `mesh` at one pose: SkinPalette of its skin (none for skin -1), then
// NodePalette of its rigid nodes. Errors name the skin or the node.
Result<std::vector<float>> MeshPalette(const Character& character, const Pose& pose,
                                       const CharacterMesh& mesh);

// MeshPalette of every mesh at one pose.
Result<std::vector<std::vector<float>>> MeshPalettes(const Character& character, const Pose& pose,
                                                     const std::vector<CharacterMesh>& meshes);

}  // namespace skinserve
