// The docs' walking character (tests/assets/gltf/WalkingFace.glb, written by
// `skinserve-test-scene walking-face` from test_scenes.h WalkingFace) end to end: the file
// on disk is imported, grouped into one mesh (skinned body and the rigid head with its morph
// targets), uploaded to a real server on loopback and streamed as `animate` streams it
// (MeshPalette and MeshMorphWeights at each frame's time), on every backend that applies
// morph targets. The weights the importer and sampler give are checked against the weights
// channel interpolated here in float64, and every vertex and normal against a float64
// morph-then-skin (or morph-then-node-transform for the head) of the scene the file was
// written from (the test's own glTF formulas). Tolerance: as morph_character_test, 1e-5 *
// (1 + the frame's largest |coordinate|) on positions, 1e-5 on normals.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iterator>

#include "clip_stream_check.h"
#include "gltf_test_support.h"
#include "skinserve/character/character_mesh.h"
#include "skinserve/character/gltf_import.h"
#include "test_scenes.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

constexpr char kAsset[] = "WalkingFace.glb";

// The head's weights (mouth open, eyes shut) at `t`: the file's LINEAR keys interpolated
// here, independently of the scene code and the importer.
std::vector<double> HeadWeights(double t) {
  const double times[] = {0, 0.4, 0.8, 1.1, 1.6, 2};
  const double keys[][2] = {{0, 0}, {1, 0}, {1, 0}, {0, 1}, {0, 1}, {0, 0}};
  std::size_t k = 0;
  while (k + 2 < std::size(times) && t >= times[k + 1]) ++k;
  const double u = std::clamp((t - times[k]) / (times[k + 1] - times[k]), 0.0, 1.0);
  return {keys[k][0] + u * (keys[k + 1][0] - keys[k][0]),
          keys[k][1] + u * (keys[k + 1][1] - keys[k][1])};
}

TEST(WalkingFaceTest, TheAssetIsTheSceneTheTestDescribes) {
  REQUIRE_ASSET(kAsset);
  // Byte for byte: the float64 reference below describes the very file the docs render.
  EXPECT_EQ(ReadBytes(AssetPath(kAsset)), WriteGlb(WalkingFace()))
      << "regenerate with: skinserve-test-scene walking-face tests/assets/gltf/" << kAsset;
}

TEST(WalkingFaceTest, EveryVertexMatchesTheFloat64MorphThenSkin) {
  REQUIRE_ASSET(kAsset);
  const Scene scene = WalkingFace();
  auto character = LoadGltfFile(AssetPath(kAsset));
  ASSERT_TRUE(character.ok()) << character.status().ToString();
  ASSERT_EQ(character->clips.size(), 1u);
  const AnimationClip& clip = character->clips[0];
  auto meshes = CharacterMeshes(*character);
  ASSERT_TRUE(meshes.ok()) << meshes.status().ToString();
  ASSERT_EQ(meshes->size(), 1u);  // the head rides with the body's skin
  const CharacterMesh& mesh = (*meshes)[0];
  ASSERT_EQ(mesh.parts.size(), 2u);  // Body/0 skinned, Head/0 rigid
  ASSERT_EQ(mesh.morph_sources.size(), 2u);
  EXPECT_EQ(mesh.rigid_nodes, (std::vector<int>{8}));

  // Mouth opening, open, closing as the eyes shut, shut, opening, and past the end.
  const std::vector<double> times = {0.0, 0.2, 0.6, 0.95, 1.3, 1.8, 2.5};
  for (double t : times) {
    std::vector<MorphWeight> sampled;
    MeshMorphWeights(mesh, SampleClip(*character, clip, t), &sampled);
    const std::vector<double> expected = HeadWeights(t);
    double got[2] = {0, 0};
    for (const MorphWeight& w : sampled) {
      ASSERT_LT(w.target, 2u);
      got[w.target] = w.weight;
    }
    EXPECT_NEAR(got[0], expected[0], 1e-6) << "mouth, t " << t;
    EXPECT_NEAR(got[1], expected[1], 1e-6) << "eyes, t " << t;
  }
  EXPECT_NEAR(HeadWeights(0.95)[0], 0.5, 1e-12);  // the interpolation itself
  EXPECT_NEAR(HeadWeights(0.95)[1], 0.5, 1e-12);

  const std::vector<ScenePrimitiveRef> prims = SkinnedPrimitives(scene);
  ASSERT_EQ(prims.size(), 2u);
  TestServer server;
  auto info = server.client->Upload(mesh.arrays);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  EXPECT_EQ(info->morph_target_count(), 2u);
  auto list = server.client->ListBackends();
  ASSERT_TRUE(list.ok());
  int backends_run = 0;
  for (const auto& backend : list->backends()) {
    if (!backend.morph_targets()) continue;
    SCOPED_TRACE(backend.id());
    ++backends_run;
    StreamClipAndCompare(*server.client, info->mesh_id(), backend.id(), scene, *character, clip,
                         mesh, times);
  }
  EXPECT_GE(backends_run, 4) << "serial, openmp, simd and simd-openmp at least";
}

// The face changes: at t = 0.6 the mouth is open (its lower lip 8 cm lower than with no
// morph) and at t = 1.3 the eyes are shut (their lids 4 cm closer); the float64 model
// shows it, so the comparison above would catch a frame sent without its weights.
TEST(WalkingFaceTest, TheReferenceFaceMovesWithTheWeights) {
  const Scene scene = WalkingFace();
  Scene still = scene;
  still.weights_channels.clear();
  const ScenePrimitiveRef head = SkinnedPrimitives(scene)[0];  // node 8 comes before node 9
  ASSERT_EQ(head.name, "Head/0");
  for (double t : {0.6, 1.3}) {
    const RefFrame morphed = SceneFrame(scene, head, t), plain = SceneFrame(still, head, t);
    double moved = 0;
    for (std::size_t i = 0; i < morphed.positions.size(); ++i) {
      moved = std::max(moved, std::fabs(morphed.positions[i] - plain.positions[i]));
    }
    EXPECT_GT(moved, 0.02) << "t " << t;
  }
}

}  // namespace
}  // namespace skinserve::testing
