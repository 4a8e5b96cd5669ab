// RawClipForMesh: which weights channels go up with a mesh's clip for the server to apply
// (skinserve-cli animate --on-server). On WalkingFace (a rigid head with 2 morph targets on
// node 8, keyed by the clip): kept when they give the mesh's targets in order, else none
// (the client then sends the weights).
#include <gtest/gtest.h>

#include "skinserve/character/character_mesh.h"
#include "skinserve/character/gltf_import.h"
#include "skinserve/character/rig.h"
#include "test_scenes.h"

namespace skinserve::testing {
namespace {

std::vector<const animation::RawTrack*> WeightsTracks(const animation::RawClip& raw) {
  std::vector<const animation::RawTrack*> out;
  for (const animation::RawTrack& t : raw.tracks) {
    if (t.path == animation::TrackPath::kWeights) out.push_back(&t);
  }
  return out;
}

TEST(RawClipForMeshTest, KeepsTheWeightsChannelsThatGiveTheMeshsTargetsInOrder) {
  const std::vector<uint8_t> glb = WriteGlb(WalkingFace());
  auto character = LoadGltfBytes(glb);
  ASSERT_TRUE(character.ok()) << character.status().ToString();
  auto meshes = CharacterMeshes(*character);
  ASSERT_TRUE(meshes.ok());
  ASSERT_EQ(meshes->size(), 1u);
  CharacterMesh mesh = (*meshes)[0];
  ASSERT_EQ(mesh.morph_sources.size(), 2u);
  auto rig = RigFromMesh(*character, mesh);
  ASSERT_TRUE(rig.ok());
  const AnimationClip& clip = character->clips.at(0);
  const animation::RawClip all = RawClipFromCharacter(clip, *rig);
  const std::size_t joint_tracks = all.tracks.size() - WeightsTracks(all).size();

  bool on_server = false;
  animation::RawClip raw = RawClipForMesh(clip, *rig, mesh, &on_server);
  EXPECT_TRUE(on_server);
  ASSERT_EQ(WeightsTracks(raw).size(), 1u);
  const animation::RawTrack& w = *WeightsTracks(raw)[0];
  EXPECT_EQ(w.target, static_cast<uint32_t>(mesh.morph_sources[0].node));
  EXPECT_EQ(w.width, 2u);
  EXPECT_EQ(w.values, WeightsTracks(all)[0]->values);
  EXPECT_EQ(raw.tracks.size(), joint_tracks + 1);

  // The mesh's targets in another order than the node's weights: none go up.
  CharacterMesh swapped = mesh;
  std::swap(swapped.morph_sources[0], swapped.morph_sources[1]);
  raw = RawClipForMesh(clip, *rig, swapped, &on_server);
  EXPECT_FALSE(on_server);
  EXPECT_TRUE(WeightsTracks(raw).empty());
  EXPECT_EQ(raw.tracks.size(), joint_tracks);

  // Only one of the node's two targets: none.
  CharacterMesh one = mesh;
  one.morph_sources.pop_back();
  raw = RawClipForMesh(clip, *rig, one, &on_server);
  EXPECT_FALSE(on_server);
  EXPECT_TRUE(WeightsTracks(raw).empty());

  // A mesh without morph targets: none.
  CharacterMesh plain = mesh;
  plain.morph_sources.clear();
  raw = RawClipForMesh(clip, *rig, plain, &on_server);
  EXPECT_FALSE(on_server);
  EXPECT_TRUE(WeightsTracks(raw).empty());
}

}  // namespace
}  // namespace skinserve::testing
