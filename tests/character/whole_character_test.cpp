// Whole characters end to end: hand-made glTF files (test_scenes.h) written by the test,
// imported, grouped into one mesh per skin with the rigid parts (CharacterMeshes), uploaded to a
// real server on loopback and streamed on every available CPU/OpenCL backend; every primitive's
// vertices and normals in each answer are compared with a float64 skinning of the scene the file
// was written from (the test's own glTF formulas, not the importer).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "clip_stream_check.h"
#include "gltf_test_support.h"
#include "skinserve/character/character_mesh.h"
#include "skinserve/character/gltf_import.h"
#include "test_scenes.h"
#include "test_server.h"

namespace skinserve::testing {
namespace {

// As in character_e2e_test.cpp: 1e-5 * (1 + S) with S bounding |M p| (here: the largest
// |coordinate| of the expected frame plus one, which bounds it for these unit-scale scenes),
// normals 1e-5.

struct Imported {
  Character character;
  std::vector<CharacterMesh> meshes;
};

Imported Import(const Scene& scene) {
  const std::vector<uint8_t> bytes = WriteGlb(scene);
  auto character = LoadGltfBytes(bytes);
  EXPECT_TRUE(character.ok()) << character.status().ToString();
  if (!character.ok()) return {};
  auto meshes = CharacterMeshes(*character);
  EXPECT_TRUE(meshes.ok()) << meshes.status().ToString();
  if (!meshes.ok()) return {};
  return {std::move(*character), std::move(*meshes)};
}

// The file's primitives, in the importer's order, are the scene's (node, primitive) pairs.
void ExpectPrimitivesAreTheScenes(const Imported& c, const Scene& scene) {
  const std::vector<ScenePrimitiveRef> expected = SkinnedPrimitives(scene);
  ASSERT_EQ(c.character.primitives.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(c.character.primitives[i].node, expected[i].node) << i;
    EXPECT_EQ(c.character.primitives[i].skin, expected[i].skin) << i;
    EXPECT_EQ(c.character.primitives[i].name, expected[i].name) << i;
  }
}

// Streams `times` through every available backend, one stream per mesh; checks every part
// of every answer against SceneFrame. Returns the number of backends run.
int ExpectServerMatchesReference(const Imported& c, const Scene& scene,
                                 const std::vector<double>& times) {
  TestServer t;
  std::vector<std::string> ids;
  for (const CharacterMesh& mesh : c.meshes) {
    auto info = t.client->Upload(mesh.arrays);
    EXPECT_TRUE(info.ok()) << info.status().ToString();
    if (!info.ok()) return 0;
    EXPECT_EQ(info->vertex_count(), mesh.arrays.vertex_count);
    ids.push_back(info->mesh_id());
  }
  auto list = t.client->ListBackends();
  EXPECT_TRUE(list.ok()) << list.status().ToString();
  if (!list.ok()) return 0;
  int backends_run = 0;
  for (const auto& backend : list->backends()) {
    if (!backend.available() || backend.id() == "passthrough") continue;
    SCOPED_TRACE(backend.id());
    ++backends_run;
    for (std::size_t m = 0; m < c.meshes.size(); ++m) {
      const CharacterMesh& mesh = c.meshes[m];
      SCOPED_TRACE(mesh.name);
      StreamClipAndCompare(*t.client, ids[m], backend.id(), scene, c.character,
                           c.character.clips[0], mesh, times);
    }
  }
  return backends_run;
}

TEST(WholeCharacterTest, SeveralPrimitivesOfOneSkinTravelAsOneMesh) {
  const Scene scene = SeveralPrimitivesOneSkin();
  const Imported c = Import(scene);
  ExpectPrimitivesAreTheScenes(c, scene);
  // Body's 3 primitives and Hat's 1, on two nodes with one skin: one mesh, four parts.
  ASSERT_EQ(c.meshes.size(), 1u);
  const CharacterMesh& mesh = c.meshes[0];
  EXPECT_EQ(mesh.skin, 0);
  ASSERT_EQ(mesh.parts.size(), 4u);
  uint32_t vertices = 0;
  std::size_t indices = 0;
  for (std::size_t i = 0; i < mesh.parts.size(); ++i) {
    const PrimitiveSpan& part = mesh.parts[i];
    const SkinnedPrimitive& p = c.character.primitives[i];
    EXPECT_EQ(part.primitive, static_cast<int>(i));
    EXPECT_EQ(part.first_vertex, vertices);
    EXPECT_EQ(part.vertex_count, p.arrays.vertex_count);
    EXPECT_EQ(part.first_index, indices);
    ASSERT_EQ(part.index_count, p.indices.size());
    for (std::size_t k = 0; k < p.indices.size(); ++k) {
      EXPECT_EQ(mesh.indices[part.first_index + k], p.indices[k] + part.first_vertex);
    }
    vertices += part.vertex_count;
    indices += part.index_count;
  }
  EXPECT_EQ(mesh.arrays.vertex_count, vertices);
  EXPECT_EQ(mesh.indices.size(), indices);
  EXPECT_EQ(mesh.arrays.joint_count, 2u);
  EXPECT_GE(ExpectServerMatchesReference(c, scene, {0.0, 0.3, 1.0, 1.7, 2.0}), 4);
}

TEST(WholeCharacterTest, TwoSkinsTravelAsTwoMeshesEachWithItsPalette) {
  const Scene scene = TwoSkins();
  const Imported c = Import(scene);
  ExpectPrimitivesAreTheScenes(c, scene);
  ASSERT_EQ(c.meshes.size(), 2u);
  EXPECT_EQ(c.meshes[0].skin, 0);
  EXPECT_EQ(c.meshes[0].parts.size(), 2u);
  EXPECT_EQ(c.meshes[1].skin, 1);
  EXPECT_EQ(c.meshes[1].parts.size(), 1u);
  EXPECT_EQ(c.meshes[1].parts[0].first_vertex, 0u);
  EXPECT_GE(ExpectServerMatchesReference(c, scene, {0.0, 0.5, 1.2, 1.5}), 4);
}

TEST(WholeCharacterTest, AMovingParentCarriesTheSkinnedMeshOnceAndItsOwnTransformIsIgnored) {
  const Scene scene = MovingParent();
  const Imported c = Import(scene);
  ExpectPrimitivesAreTheScenes(c, scene);
  ASSERT_EQ(c.meshes.size(), 1u);
  const std::vector<double> times = {0.0, 0.5, 1.0, 1.6, 2.0};
  EXPECT_GE(ExpectServerMatchesReference(c, scene, times), 4);

  // Only Mover is animated and the clip starts at the rest pose, so each vertex at time t is
  // its bind position carried by Mover's motion: W(t) * W(0)^-1 * p. No palette, no inverse
  // bind, no skinning code: if the mesh node's own transform were applied, or Mover's
  // twice, this fails.
  const CharacterMesh& mesh = c.meshes[0];
  for (double t : times) {
    const Mat4 now = WorldMatrix(scene, 0, t), rest = WorldMatrix(scene, 0, 0.0);
    auto palette =
        SkinPalette(c.character, SampleClip(c.character, c.character.clips[0], t), mesh.skin);
    ASSERT_TRUE(palette.ok()) << palette.status().ToString();
    for (std::size_t v = 0; v < mesh.arrays.vertex_count; ++v) {
      const float* p = &mesh.arrays.positions[3 * v];
      // rest^-1 * p (rest is rigid: transpose of its rotation), then now * that.
      double local[3];
      for (int r = 0; r < 3; ++r) {
        local[r] = 0;
        for (int k = 0; k < 3; ++k) local[r] += rest[4 * r + k] * (p[k] - rest[12 + k]);
      }
      double expected[3];
      for (int r = 0; r < 3; ++r) {
        expected[r] = now[12 + r];
        for (int k = 0; k < 3; ++k) expected[r] += now[4 * k + r] * local[k];
      }
      // The float64 skinning of the importer's palette must land there too.
      const std::size_t b = mesh.arrays.influences;
      for (int r = 0; r < 3; ++r) {
        double got = 0;
        for (std::size_t i = 0; i < b; ++i) {
          const float* row = &(*palette)[12 * mesh.arrays.joints[v * b + i] + 4 * r];
          got += mesh.arrays.weights[v * b + i] *
                 (row[0] * double{p[0]} + row[1] * double{p[1]} + row[2] * double{p[2]} + row[3]);
        }
        EXPECT_NEAR(got, expected[r], 1e-5) << "vertex " << v << " t " << t;
      }
    }
  }
}

// Rigid parts: meshes on nodes without a skin join the skin's mesh, each node one palette
// entry past the skin's joints, so the character with normals is one mesh and one request.
TEST(WholeCharacterTest, RigidPartsFollowTheirNodesInTheSkinsMesh) {
  const Scene scene = RigidParts();
  const Imported c = Import(scene);
  ExpectPrimitivesAreTheScenes(c, scene);
  // Helmet/0, Helmet/1 on node 3, Body/0 (skinned), Helmet/0, Helmet/1 on node 6: normals;
  // Shield/0 on node 5: none.
  ASSERT_EQ(c.meshes.size(), 2u);
  const CharacterMesh& with = c.meshes[0];
  EXPECT_EQ(with.skin, 0);
  EXPECT_EQ(with.rigid_nodes, (std::vector<int>{3, 6}));
  EXPECT_EQ(with.arrays.joint_count, 4u);  // Hip, Knee, then nodes 3 and 6
  ASSERT_EQ(with.parts.size(), 5u);
  const CharacterMesh& without = c.meshes[1];
  EXPECT_EQ(without.rigid_nodes, (std::vector<int>{5}));
  EXPECT_EQ(without.arrays.joint_count, 3u);
  ASSERT_EQ(without.parts.size(), 1u);
  // Every vertex of a rigid part has one influence: its node's entry, weight 1.
  for (const CharacterMesh* mesh : {&with, &without}) {
    const std::size_t b = mesh->arrays.influences;
    for (const PrimitiveSpan& part : mesh->parts) {
      const SkinnedPrimitive& p = c.character.primitives[static_cast<std::size_t>(part.primitive)];
      if (!p.rigid()) continue;
      const auto place = std::find(mesh->rigid_nodes.begin(), mesh->rigid_nodes.end(), p.node) -
                         mesh->rigid_nodes.begin();
      for (uint32_t v = part.first_vertex; v < part.first_vertex + part.vertex_count; ++v) {
        EXPECT_EQ(mesh->arrays.joints[v * b], 2 + place) << part.name;
        EXPECT_EQ(mesh->arrays.weights[v * b], 1.0f) << part.name;
        for (std::size_t i = 1; i < b; ++i) EXPECT_EQ(mesh->arrays.weights[v * b + i], 0.0f);
      }
    }
  }
  EXPECT_GE(ExpectServerMatchesReference(c, scene, {0.0, 0.4, 1.0, 1.3, 2.0}), 4);
}

// KHR_mesh_quantization as gltfpack writes it: integer attributes, dequantized by the rigid
// mesh node's transform or the skin's inverse bind matrices.
TEST(WholeCharacterTest, QuantizedAttributesSkinAsTheirDequantizedValues) {
  const Scene scene = Quantized();
  const Imported c = Import(scene);
  ExpectPrimitivesAreTheScenes(c, scene);
  ASSERT_EQ(c.meshes.size(), 1u);
  EXPECT_EQ(c.meshes[0].parts.size(), 4u);
  // The stored integers, not normalized ones: the int16 box's positions are whole numbers
  // well beyond 1.
  const SkinnedPrimitive& box = c.character.primitives[2];
  ASSERT_TRUE(box.rigid());
  float largest = 0;
  for (float x : box.arrays.positions) {
    EXPECT_EQ(x, std::round(x));
    largest = std::max(largest, std::fabs(x));
  }
  EXPECT_GT(largest, 100.0f);
  EXPECT_GE(ExpectServerMatchesReference(c, scene, {0.0, 0.7, 1.0, 1.5, 2.0}), 4);
}

TEST(WholeCharacterTest, SparseAccessorsAreSubstituted) {
  const Scene scene = Sparse();
  const Imported c = Import(scene);
  ExpectPrimitivesAreTheScenes(c, scene);
  ASSERT_EQ(c.meshes.size(), 1u);
  // The base's garbage (99) under the substituted vertices never shows.
  for (float x : c.meshes[0].arrays.positions) EXPECT_LT(std::fabs(x), 10.0f);
  EXPECT_GE(ExpectServerMatchesReference(c, scene, {0.0, 0.5, 1.1, 2.0}), 4);
}

}  // namespace
}  // namespace skinserve::testing
