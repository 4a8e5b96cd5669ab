// A character with morph targets driven by a weights channel, end to end: a hand-made glTF
// (test_scenes.h MorphFace: targets with POSITION and NORMAL deltas, default mesh weights,
// a weights channel per interpolation, LINEAR, STEP and CUBICSPLINE) written by the test,
// imported, grouped into one mesh (CharacterMeshes), uploaded to a real server on loopback
// and streamed with each frame's weights sampled with its palette, as `animate` does, on
// every backend that applies morph targets. Every primitive's vertices and normals are
// compared with a float64 morph-then-skin of the scene the file was written from (the
// test's own glTF formulas, not the importer). Tolerance: as whole_character_test, 1e-5 *
// (1 + the frame's largest |coordinate|) on positions, 1e-5 on normals.
#include <gtest/gtest.h>

#include <cmath>

#include "clip_stream_check.h"
#include "gltf_test_support.h"
#include "skinserve/character/character_mesh.h"
#include "skinserve/character/gltf_import.h"
#include "test_scenes.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

class MorphCharacterTest : public ::testing::TestWithParam<std::string> {};

TEST_P(MorphCharacterTest, EveryPrimitiveMatchesTheFloat64MorphThenSkin) {
  const Scene scene = MorphFace(GetParam());
  auto character = LoadGltfBytes(WriteGlb(scene));
  ASSERT_TRUE(character.ok()) << character.status().ToString();
  // Imported as the file states: default weights per node, the weights channel kept.
  EXPECT_EQ(character->nodes[3].weights, (std::vector<float>{0.25f, 0.0f, -0.5f}));
  EXPECT_EQ(character->nodes[4].weights, (std::vector<float>{0.5f, 1.0f}));
  ASSERT_EQ(character->clips.size(), 1u);
  int weight_channels = 0;
  for (const AnimationChannel& ch : character->clips[0].channels) {
    weight_channels += ch.path == ChannelPath::kWeights ? 1 : 0;
  }
  EXPECT_EQ(weight_channels, 1);
  auto meshes = CharacterMeshes(*character);
  ASSERT_TRUE(meshes.ok()) << meshes.status().ToString();
  ASSERT_EQ(meshes->size(), 1u);
  const CharacterMesh& mesh = (*meshes)[0];
  ASSERT_EQ(mesh.parts.size(), 3u);                  // Face/0, Face/1, Brow/0
  ASSERT_EQ(mesh.morph_sources.size(), 3u + 3 + 2);  // their targets, part after part
  EXPECT_EQ(mesh.morph_sources[6].node, 4);
  EXPECT_EQ(mesh.morph_sources[6].target, 0u);
  // Sparse: target 0 of each Face primitive moves every other vertex only.
  EXPECT_EQ(mesh.arrays.morph_target_sizes[0], (mesh.parts[0].vertex_count + 1) / 2);

  const std::vector<double> times = {0.0, 0.3, 0.75, 0.8, 1.37, 2.0, 2.5};
  TestServer t;
  auto info = t.client->Upload(mesh.arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  EXPECT_EQ(info->morph_target_count(), 8u);
  auto list = t.client->ListBackends();
  ASSERT_TRUE(list.ok());
  int backends_run = 0;
  for (const auto& backend : list->backends()) {
    if (!backend.morph_targets()) continue;
    SCOPED_TRACE(backend.id());
    ++backends_run;
    StreamClipAndCompare(*t.client, info->mesh_id(), backend.id(), scene, *character,
                         character->clips[0], mesh, times);
  }
  EXPECT_GE(backends_run, 4) << "serial, openmp, simd and simd-openmp at least";
}

INSTANTIATE_TEST_SUITE_P(Interpolations, MorphCharacterTest,
                         ::testing::Values("LINEAR", "STEP", "CUBICSPLINE"));

// The morphs matter: at t = 0.75 the Face's weights are (1, -0.5, 0.7), so a frame without
// them would be far from the reference; the float64 model itself shows it.
TEST(MorphCharacterTest, TheReferenceMovesWithTheWeights) {
  const Scene scene = MorphFace("LINEAR");
  Scene still = scene;
  for (SceneMesh& m : still.meshes) std::fill(m.weights.begin(), m.weights.end(), 0.0);
  still.weights_channels.clear();
  const ScenePrimitiveRef face = SkinnedPrimitives(scene)[0];
  const RefFrame morphed = SceneFrame(scene, face, 0.75), plain = SceneFrame(still, face, 0.75);
  double moved = 0;
  for (std::size_t i = 0; i < morphed.positions.size(); ++i) {
    moved = std::max(moved, std::fabs(morphed.positions[i] - plain.positions[i]));
  }
  EXPECT_GT(moved, 0.01);
}

}  // namespace
}  // namespace skinserve::testing
