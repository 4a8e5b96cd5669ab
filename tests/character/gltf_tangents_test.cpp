// glTF TANGENT import: float and KHR_mesh_quantization normalized SHORT tangents (one
// sparse), renormalised and snapped, and morph targets' TANGENT deltas (float and
// normalized SHORT), checked value by value against what the test wrote (tangent_scene.h);
// grouping into character meshes; TANGENT without NORMAL ignored with a warning; bad
// tangents refused naming the primitive, the accessor and the vertex.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>

#include "skinserve/character/character_mesh.h"
#include "skinserve/character/gltf_import.h"
#include "tangent_scene.h"

namespace skinserve::testing {
namespace {

Result<Character> Load(const Glb& glb) { return LoadGltfBytes(BuildGlb(glb)); }

// The written tangent renormalised in float64, w its sign: what the importer must give.
void ExpectTangents(const TangentScenePrimitive& p, std::span<const float> got,
                    const std::string& what) {
  ASSERT_EQ(got.size(), 4 * p.vertex_count) << what;
  for (std::size_t v = 0; v < p.vertex_count; ++v) {
    const double* t = &p.tangents[4 * v];
    const double length = std::sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(got[4 * v + c], t[c] / length, 1e-6) << what << " vertex " << v << " " << c;
    }
    EXPECT_EQ(got[4 * v + 3], t[3] > 0 ? 1.0f : -1.0f) << what << " vertex " << v << " w";
  }
}

TEST(GltfTangentsTest, FloatAndQuantizedTangentsAreRenormalisedAndTheirHandednessSnapped) {
  const TangentScene scene = MakeTangentScene();
  auto character = Load(scene.glb);
  ASSERT_TRUE(character.ok()) << character.status().ToString();
  ASSERT_EQ(character->primitives.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    const SkinnedPrimitive& got = character->primitives[i];
    EXPECT_TRUE(got.warnings.empty()) << got.warnings.front();
    ExpectTangents(scene.primitives[i], got.arrays.tangents, got.name);
  }
  // The quantized primitive's tangents are exact shorts: xyz were unit before rounding, so
  // renormalising moves them by less than a short's step.
  const TangentScenePrimitive& q = scene.primitives[1];
  for (std::size_t k = 0; k < 12; ++k) {
    EXPECT_NEAR(character->primitives[1].arrays.tangents[k], q.tangents[k], 1.0 / 32767) << k;
  }
}

TEST(GltfTangentsTest, MorphTangentDeltasAreReadSparseBesideThePositionAndNormalDeltas) {
  const TangentScene scene = MakeTangentScene();
  auto character = Load(scene.glb);
  ASSERT_TRUE(character.ok()) << character.status().ToString();
  const TangentScenePrimitive& p = scene.primitives[0];
  const MeshArrays& a = character->primitives[0].arrays;
  // Target 0 moves vertices 0, 2 (position; 2 also normal) and 3 (tangent only); target 1
  // vertices 0, 1 (tangent only) and 4 (position only).
  ASSERT_EQ(a.morph_target_sizes, (std::vector<uint32_t>{3, 3}));
  ASSERT_EQ(a.morph_indices, (std::vector<uint32_t>{0, 2, 3, 0, 1, 4}));
  ASSERT_EQ(a.morph_tangent_deltas.size(), 18u);
  ASSERT_EQ(a.morph_normal_deltas.size(), 18u);
  for (std::size_t k = 0; k < 6; ++k) {
    const std::size_t t = k / 3, v = a.morph_indices[k];
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(a.morph_position_deltas[3 * k + c], p.target_positions[t][3 * v + c], 1e-7);
      EXPECT_NEAR(a.morph_tangent_deltas[3 * k + c], p.target_tangents[t][3 * v + c], 1e-7)
          << "target " << t << " vertex " << v << " " << c;
      const double normal = p.target_normals[t].empty() ? 0.0 : p.target_normals[t][3 * v + c];
      EXPECT_NEAR(a.morph_normal_deltas[3 * k + c], normal, 1e-7);
    }
  }
  EXPECT_TRUE(character->primitives[1].arrays.morph_tangent_deltas.empty());
}

TEST(GltfTangentsTest, ACharacterMeshCarriesEveryPartsTangentsAndTheirMorphDeltas) {
  const TangentScene scene = MakeTangentScene();
  auto character = Load(scene.glb);
  ASSERT_TRUE(character.ok()) << character.status().ToString();
  auto meshes = CharacterMeshes(*character);
  ASSERT_TRUE(meshes.ok()) << meshes.status().ToString();
  ASSERT_EQ(meshes->size(), 1u);
  const MeshArrays& a = meshes->front().arrays;
  ExpectTangents(scene.primitives[0], std::span<const float>(a.tangents).first(20), "part 0");
  ExpectTangents(scene.primitives[1], std::span<const float>(a.tangents).subspan(20), "part 1");
  EXPECT_EQ(a.morph_tangent_deltas, character->primitives[0].arrays.morph_tangent_deltas);
  EXPECT_TRUE(Mesh::Create(a).ok());

  // A part without TANGENT goes into a mesh of its own: a mesh has tangents for all of its
  // vertices or none.
  TangentScene split = MakeTangentScene();
  split.glb.json["meshes"][1]["primitives"][0]["attributes"].erase("TANGENT");
  character = Load(split.glb);
  ASSERT_TRUE(character.ok()) << character.status().ToString();
  meshes = CharacterMeshes(*character);
  ASSERT_TRUE(meshes.ok()) << meshes.status().ToString();
  ASSERT_EQ(meshes->size(), 2u);
  EXPECT_EQ((*meshes)[0].name, "skins[0] (tangents)");
  EXPECT_EQ((*meshes)[0].arrays.tangents.size(), 20u);
  EXPECT_EQ((*meshes)[0].arrays.morph_tangent_deltas.size(), 18u);
  EXPECT_EQ((*meshes)[1].name, "skins[0] (no tangents)");
  EXPECT_TRUE((*meshes)[1].arrays.tangents.empty());
  EXPECT_EQ((*meshes)[1].arrays.normals.size(), 9u);
}

TEST(GltfTangentsTest, TangentWithoutNormalIsIgnoredWithAWarningAsTheSpecSays) {
  TangentScene scene = MakeTangentScene();
  scene.glb.json["meshes"][1]["primitives"][0]["attributes"].erase("NORMAL");
  auto character = Load(scene.glb);
  ASSERT_TRUE(character.ok()) << character.status().ToString();
  const SkinnedPrimitive& p = character->primitives[1];
  EXPECT_TRUE(p.arrays.normals.empty());
  EXPECT_TRUE(p.arrays.tangents.empty());
  ASSERT_EQ(p.warnings.size(), 1u);
  EXPECT_EQ(p.warnings[0],
            "meshes[1].primitives[0].attributes.TANGENT ignored: the primitive has no NORMAL, and "
            "glTF ignores tangents without normals");
  // Its morph TANGENT deltas go with it: primitive 0 without NORMAL keeps its targets'
  // positions only.
  scene = MakeTangentScene();
  scene.glb.json["meshes"][0]["primitives"][0]["attributes"].erase("NORMAL");
  character = Load(scene.glb);
  ASSERT_TRUE(character.ok()) << character.status().ToString();
  EXPECT_TRUE(character->primitives[0].arrays.morph_tangent_deltas.empty());
  EXPECT_TRUE(character->primitives[0].arrays.morph_normal_deltas.empty());
  EXPECT_EQ(character->primitives[0].arrays.morph_indices, (std::vector<uint32_t>{0, 2, 4}));
}

class GltfBadTangentsTest : public ::testing::Test {
 protected:
  TangentScene scene_ = MakeTangentScene();

  float* FloatAt(int accessor, std::size_t vertex, int c) {
    return reinterpret_cast<float*>(scene_.glb.bin.data() +
                                    ElementOffset(scene_.glb, accessor, vertex)) +
           c;
  }
  nlohmann::json& AccessorJson(int accessor) {
    return scene_.glb.json["accessors"][static_cast<std::size_t>(accessor)];
  }
  void ExpectInvalid(const std::vector<std::string>& parts) {
    auto character = Load(scene_.glb);
    ASSERT_FALSE(character.ok());
    EXPECT_EQ(character.status().code(), StatusCode::kInvalidArgument);
    for (const std::string& part : parts) {
      EXPECT_NE(character.status().message().find(part), std::string::npos)
          << "'" << part << "' not in: " << character.status().message();
    }
  }
};

TEST_F(GltfBadTangentsTest, XyzFartherFromUnitThanTheToleranceIsRefusedNamingTheVertex) {
  const int a = scene_.primitives[0].tangent_accessor;
  for (int c = 0; c < 3; ++c) *FloatAt(a, 2, c) *= 0.98f / 0.994f;
  ExpectInvalid({"meshes[0].primitives[0].attributes.TANGENT: accessor " + std::to_string(a) +
                     " vertex 2 xyz has length 0.98",
                 "unit vector within 0.01"});
  *FloatAt(a, 2, 0) = std::numeric_limits<float>::quiet_NaN();
  ExpectInvalid({"attributes.TANGENT", "vertex 2 xyz has length nan"});
}

TEST_F(GltfBadTangentsTest, AHandednessNotNearPlusOrMinusOneIsRefused) {
  const int a = scene_.primitives[0].tangent_accessor;
  *FloatAt(a, 1, 3) = 0.5f;
  ExpectInvalid({"meshes[0].primitives[0].attributes.TANGENT: accessor " + std::to_string(a) +
                 " vertex 1 w = 0.5; the handedness must be +1 or -1 within 0.01"});
  *FloatAt(a, 1, 3) = -0.985f;
  ExpectInvalid({"vertex 1 w = -0.985"});
}

TEST_F(GltfBadTangentsTest, TypesTheSpecDoesNotAllowAreRefusedNamingTheAccessor) {
  const int q = scene_.primitives[1].tangent_accessor;
  AccessorJson(q).erase("normalized");
  ExpectInvalid({"meshes[1].primitives[0].attributes.TANGENT: accessor " + std::to_string(q) +
                     " has componentType SHORT without normalized: true",
                 "KHR_mesh_quantization"});
  AccessorJson(q)["normalized"] = true;
  AccessorJson(q)["componentType"] = 5123;  // UNSIGNED_SHORT
  ExpectInvalid({"attributes.TANGENT", "componentType 5123", "allowed: FLOAT, BYTE, SHORT"});
  AccessorJson(q)["componentType"] = 5122;
  AccessorJson(q)["type"] = "VEC3";
  ExpectInvalid({"attributes.TANGENT", "has type VEC3; expected VEC4"});
  AccessorJson(q)["type"] = "VEC4";
  AccessorJson(q)["count"] = 2;
  ExpectInvalid({"attributes.TANGENT", "has count 2; POSITION has 3 vertices"});
}

TEST_F(GltfBadTangentsTest, BadMorphTangentDeltasAreRefusedNamingTheTarget) {
  const int d = scene_.primitives[0].target_tangent_accessors[1];
  AccessorJson(d).erase("normalized");
  ExpectInvalid({"meshes[0].primitives[0].targets[1].TANGENT: accessor " + std::to_string(d) +
                 " has componentType SHORT without normalized: true"});
  AccessorJson(d)["normalized"] = true;
  AccessorJson(d)["type"] = "VEC4";
  ExpectInvalid({"targets[1].TANGENT", "has type VEC4; expected VEC3"});
  AccessorJson(d)["type"] = "VEC3";
  *FloatAt(scene_.primitives[0].target_tangent_accessors[0], 3, 0) = 5.0f;
  ExpectInvalid(
      {"meshes[0].primitives[0]: morph_tangent_deltas[target 0, delta 2].x = 5", "within +-4"});
}

}  // namespace
}  // namespace skinserve::testing
