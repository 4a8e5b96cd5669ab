// skinserve-load's glTF workload (client/load/workload.h) on a written two-skin character:
// the skins concatenated into one mesh with one palette per frame must skin every primitive
// where the float64 skinning of the scene puts it (test_scenes.h), at the clip time each
// frame stands for.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "skinserve/reference/reference.h"
#include "test_scenes.h"
#include "workload.h"

namespace skinserve::testing {
namespace {

TEST(CharacterWorkloadTest, TwoSkinsAsOneMeshAndOnePaletteSkinLikeTheScene) {
  const Scene scene = TwoSkins();
  const std::string path = ::testing::TempDir() + "workload-two-skins.glb";
  {
    const std::vector<uint8_t> glb = WriteGlb(scene);
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(glb.data()), static_cast<std::streamsize>(glb.size()));
  }
  auto w = load::MakeGltfWorkload(path, -1, true);
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  const std::vector<ScenePrimitiveRef> prims = SkinnedPrimitives(scene);
  uint32_t vertices = 0;
  for (const ScenePrimitiveRef& p : prims) {
    vertices += static_cast<uint32_t>(scene.meshes[static_cast<std::size_t>(p.mesh)]
                                          .primitives[static_cast<std::size_t>(p.primitive)]
                                          .positions.size() /
                                      3);
  }
  EXPECT_EQ(w->vertices, vertices);
  EXPECT_EQ(w->joints, 4u);  // 2 + 2
  // 1.5 s at 30 frames per second.
  EXPECT_EQ(w->palettes.size(), 45u);
  for (uint64_t f : {0u, 7u, 22u, 44u}) {
    const ReferenceFrame got = ReferenceSkin(*w->mesh, w->Palette(f));
    const double t = static_cast<double>(f) / load::kGltfWorkloadFps;
    std::size_t first = 0;  // the importer's order: skin 0's primitives, then skin 1's
    for (const ScenePrimitiveRef& p : prims) {
      const RefFrame expected = SceneFrame(scene, p, t);
      for (std::size_t i = 0; i < expected.positions.size(); ++i) {
        ASSERT_NEAR(got.positions[3 * first + i], expected.positions[i], 1e-5)
            << p.name << " vertex " << i / 3 << " frame " << f;
        ASSERT_NEAR(got.normals[3 * first + i], expected.normals[i], 1e-5)
            << p.name << " vertex " << i / 3 << " frame " << f;
      }
      first += expected.positions.size() / 3;
    }
  }
  // One primitive alone: that primitive's vertices only.
  auto one = load::MakeGltfWorkload(path, 2, false);
  ASSERT_TRUE(one.ok()) << one.status().ToString();
  EXPECT_EQ(one->vertices, 8u);
  EXPECT_EQ(load::MakeGltfWorkload(path, 3, false).status().message(),
            "--primitive 3 is not below the 3 primitive(s) (skinned and rigid) of " + path);
}

}  // namespace
}  // namespace skinserve::testing
