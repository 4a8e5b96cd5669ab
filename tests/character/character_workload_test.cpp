// skinserve-load's glTF workload (client/load/workload.h) on a written two-skin character:
// the skins concatenated into one mesh with one palette per frame must skin every primitive
// where the float64 skinning of the scene puts it (test_scenes.h), at the clip time each
// frame stands for; with morph targets, morphed by each frame's weights first. The load
// client itself runs on the morph character against a real server on loopback.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>

#include "skinserve/reference/reference.h"
#include "test_scenes.h"
#include "test_server.h"
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
  // Its triangles (Workload::indices, for renderers): each primitive's, renumbered past
  // the vertices of the primitives before it.
  std::vector<uint32_t> triangles;
  uint32_t base = 0;
  for (const ScenePrimitiveRef& p : prims) {
    const auto& primitive = scene.meshes[static_cast<std::size_t>(p.mesh)]
                                .primitives[static_cast<std::size_t>(p.primitive)];
    for (uint16_t index : primitive.indices) triangles.push_back(base + index);
    base += static_cast<uint32_t>(primitive.positions.size() / 3);
  }
  EXPECT_FALSE(triangles.empty());
  EXPECT_EQ(w->indices, triangles);
  // One primitive alone: that primitive's vertices only.
  auto one = load::MakeGltfWorkload(path, 2, false);
  ASSERT_TRUE(one.ok()) << one.status().ToString();
  EXPECT_EQ(one->vertices, 8u);
  EXPECT_EQ(load::MakeGltfWorkload(path, 3, false).status().message(),
            "--primitive 3 is not below the 3 primitive(s) (skinned and rigid) of " + path);
}

// MorphFace as a file; with `two_skins` its Brow follows a second skin (the same joints),
// so that the workload concatenates two meshes and their morph targets.
std::string WriteMorphFace(bool two_skins) {
  Scene scene = MorphFace("LINEAR");
  if (two_skins) {
    scene.skins.push_back(scene.skins[0]);
    scene.nodes[4].skin = 1;
  }
  const std::string path =
      ::testing::TempDir() + (two_skins ? "workload-morph-two-skins.glb" : "workload-morph.glb");
  const std::vector<uint8_t> glb = WriteGlb(scene);
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(glb.data()), static_cast<std::streamsize>(glb.size()));
  return path;
}

// The workload's morph targets and per-frame weights: its mesh morphed by frame f's weights
// and skinned by frame f's palette lies where the float64 morph-then-skin of the scene puts
// every primitive at f / 30 s, with one mesh or two concatenated.
TEST(CharacterWorkloadTest, MorphTargetsAndTheirWeightsFollowTheClip) {
  for (const bool two_skins : {false, true}) {
    SCOPED_TRACE(two_skins ? "two skins" : "one skin");
    Scene scene = MorphFace("LINEAR");
    if (two_skins) {
      scene.skins.push_back(scene.skins[0]);
      scene.nodes[4].skin = 1;
    }
    auto w = load::MakeGltfWorkload(WriteMorphFace(two_skins), -1, true);
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    EXPECT_EQ(w->mesh->morph_target_count(), 8u);  // Face 3 + 3, Brow 2
    EXPECT_EQ(w->joints, two_skins ? 4u : 2u);
    ASSERT_EQ(w->morph_weights.size(), w->palettes.size());
    EXPECT_FALSE(w->Morph(22).empty());
    const std::vector<ScenePrimitiveRef> prims = SkinnedPrimitives(scene);
    for (uint64_t f : {0u, 9u, 22u, 40u, 59u}) {
      const ReferenceFrame got = ReferenceSkin(*w->mesh, w->Palette(f), w->Morph(f));
      const double t = static_cast<double>(f) / load::kGltfWorkloadFps;
      std::size_t first = 0;
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
      ASSERT_EQ(3 * first, got.positions.size());
    }
  }
}

// skinserve-load --mesh on the morph character, through a real server: every answer
// checked against the float64 reference of the morphed mesh, none off, on a crowd too
// (weights per instance). The check is not vacuous: `passthrough`, which applies no
// morph targets, is refused the frames that carry weights.
TEST(CharacterWorkloadTest, LoadClientSendsAndChecksTheCharactersMorphWeights) {
  TestServer t;
  const std::string path = WriteMorphFace(true);
  int run = 0;
  for (const std::string extra :
       {" --backends serial,simd", " --backends simd --instances 3", " --backends passthrough"}) {
    SCOPED_TRACE(extra);
    const std::string json = ::testing::TempDir() + "load-morph-" + std::to_string(getpid()) + "-" +
                             std::to_string(run++) + ".json";
    const std::string command =
        std::string(SKINSERVE_LOAD_BINARY) + " --target " + t.target + " --mesh " + path + extra +
        " --normals --frames 60 --warmup 0 --check-every 1 --json " + json + " > /dev/null 2>&1";
    const int status = std::system(command.c_str());
    std::ifstream in(json);
    ASSERT_TRUE(in) << command;
    nlohmann::json doc;
    in >> doc;
    ASSERT_FALSE(doc["results"].empty());
    for (const auto& r : doc["results"]) {
      if (extra.find("passthrough") != std::string::npos) {
        EXPECT_GT(r["errors"].value("FAILED_PRECONDITION", 0), 0) << r.dump();
        continue;
      }
      EXPECT_EQ(WEXITSTATUS(status), 0) << command;
      EXPECT_TRUE(r["errors"].empty()) << r.dump();
      EXPECT_GE(r["checked"].get<uint64_t>(), 60u) << r.dump();
      EXPECT_EQ(r["mismatches"], 0) << r.dump();
    }
  }
}

}  // namespace
}  // namespace skinserve::testing
