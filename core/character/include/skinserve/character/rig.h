// A glTF character's skin and clips as the animation runtime's inputs
// (skinserve/animation): the skeleton and raw clips the server stores and samples.
#pragma once

#include <vector>

#include "skinserve/animation/raw_clip.h"
#include "skinserve/animation/skeleton.h"
#include "skinserve/character/character.h"
#include "skinserve/character/character_mesh.h"
#include "skinserve/model/status.h"

namespace skinserve {

struct Rig {
  animation::Skeleton skeleton;
  std::vector<int> nodes;  // the character's node of each skeleton joint
};

// The skin's joints and their ancestors (an armature node above them moves them too),
// parents before children; palette entry p is skin.joints[p] with its inverse bind.
// INVALID_ARGUMENT for a bad skin index or an inverse bind that is not affine.
Result<Rig> RigFromSkin(const Character& character, int skin);

// The rig whose palette is MeshPalette's for `mesh`: its skin's joints with their inverse
// binds (none for skin -1), then its rigid nodes with the identity (their vertices are in
// the node's space), with every ancestor of them. INVALID_ARGUMENT naming the mesh when it
// has neither, or as RigFromSkin.
Result<Rig> RigFromMesh(const Character& character, const CharacterMesh& mesh);

// The clip's channels on the rig's joints and its morph weights channels (target: the
// glTF node). Channels on nodes outside the rig (rigid parts' nodes) are left out.
animation::RawClip RawClipFromCharacter(const AnimationClip& clip, const Rig& rig);

// RawClipFromCharacter for one mesh, as the server applies it: the server takes a clip's
// weights tracks, in order, as the mesh's morph target weights. So the weights channels are
// kept, in the order of the mesh's morph_sources, only when each of the mesh's morph nodes
// has one channel whose weights are that node's targets in order (`*weights_on_server` set
// true); else, or for a mesh without morph targets, none are (the caller sends the weights).
animation::RawClip RawClipForMesh(const AnimationClip& clip, const Rig& rig,
                                  const CharacterMesh& mesh, bool* weights_on_server);

}  // namespace skinserve
