// A whole character as the server needs it: its skinned primitives grouped by skin, each
// group one mesh (the primitives' vertices one after another). A skin's primitives share
// one palette per frame, so a group travels as one upload and one stream, however many
// pieces the file split the character into.
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

// Primitives of one skin, concatenated.
//  - arrays: positions, normals (all or none of the parts have them), joints/weights padded
//    to the largest influence count of the parts (weight 0, joint 0), joint_count = the
//    skin's joints.
//  - indices: every part's triangles, renumbered into the concatenated vertices.
//  - morph_sources: one per morph target of `arrays` (every part's targets, part after
//    part, their vertices renumbered), naming the node weight that drives it.
struct CharacterMesh {
  int skin = -1;
  std::string name;  // the skin's name, or "skins[N]"; with " (normals)" / " (no normals)"
                     // when the skin's parts are split on that
  MeshArrays arrays;
  std::vector<uint32_t> indices;
  std::vector<PrimitiveSpan> parts;  // in the file's order
  std::vector<MorphTargetSource> morph_sources;
};

// The character's meshes: one per skin, in order of the skins' first primitive. Parts of
// one skin that disagree on normals go into two meshes (with, without), since a mesh has
// normals for all of its vertices or none. `only` >= 0 takes that primitive alone.
// INVALID_ARGUMENT when `only` is not a primitive, or a skin's parts exceed 2^32 - 1
// vertices.
Result<std::vector<CharacterMesh>> CharacterMeshes(const Character& character, int only = -1);

// The mesh's non-zero morph target weights at `pose` (sparse, as a frame carries them),
// into `out` (its capacity reused).
void MeshMorphWeights(const CharacterMesh& mesh, const Pose& pose, std::vector<MorphWeight>* out);

// The palette of every mesh at one pose: SkinPalette of each mesh's skin, computed once per
// skin. Errors name the skin.
Result<std::vector<std::vector<float>>> MeshPalettes(const Character& character, const Pose& pose,
                                                     const std::vector<CharacterMesh>& meshes);

}  // namespace skinserve
