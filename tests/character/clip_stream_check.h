// One clip of a test character streamed through a real server and every part of every
// answer compared with the float64 frame of the scene the character was written from
// (test_scenes.h SceneFrame: the test's own glTF formulas, not the importer). Shared by
// the whole-character, morph-character and walking-face tests.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "skinserve/character/animation.h"
#include "skinserve/character/character_mesh.h"
#include "skinserve/character/gltf_import.h"
#include "skinserve/client/skin_client.h"
#include "test_scenes.h"

namespace skinserve::testing {

// Streams `times` (seconds into `clip`) on `backend` as one stream of `mesh_id`, the
// uploaded `mesh`: each frame's palette is MeshPalette at that pose (skinned and rigid
// parts), its morph weights MeshMorphWeights (none where the mesh has no targets), normals
// asked for where the mesh has them. Checks every answer's parts against SceneFrame:
// positions within 1e-5 * (1 + the frame's largest |coordinate|), normals within 1e-5.
// Failures are reported through gtest; returns the frames answered.
uint64_t StreamClipAndCompare(client::SkinClient& client, const std::string& mesh_id,
                              const std::string& backend, const Scene& scene,
                              const Character& character, const AnimationClip& clip,
                              const CharacterMesh& mesh, const std::vector<double>& times);

}  // namespace skinserve::testing
