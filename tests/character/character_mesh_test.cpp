// CharacterMeshes on hand-built characters: what goes together, in which order, padded how,
// and what a single --primitive gives.
#include "skinserve/character/character_mesh.h"

#include <gtest/gtest.h>

namespace skinserve::testing {
namespace {

// A primitive of `vertices` vertices on `skin`, `influences` per vertex (joint = vertex %
// joints, the rest padding), a triangle fan for indices, normals when asked.
SkinnedPrimitive Part(const std::string& name, int skin, uint32_t vertices, uint32_t influences,
                      uint32_t joints, bool normals) {
  SkinnedPrimitive p;
  p.name = name;
  p.skin = skin;
  MeshArrays& a = p.arrays;
  a.vertex_count = vertices;
  a.influences = influences;
  a.joint_count = joints;
  for (uint32_t v = 0; v < vertices; ++v) {
    a.positions.insert(a.positions.end(), {float(v), float(skin), 0.5f});
    if (normals) a.normals.insert(a.normals.end(), {0, 0, 1});
    for (uint32_t i = 0; i < influences; ++i) {
      a.joints.push_back(static_cast<uint16_t>((v + i) % joints));
      a.weights.push_back(i == 0 ? 1.0f : 0.0f);
    }
  }
  for (uint32_t v = 1; v + 1 < vertices; ++v) p.indices.insert(p.indices.end(), {0, v, v + 1});
  return p;
}

Character Make() {
  Character c;
  c.skins.resize(2);
  c.skins[0].name = "Body";
  c.skins[0].joints = {0, 1, 2};
  c.skins[1].joints = {3, 4};
  c.primitives.push_back(Part("a/0", 0, 4, 4, 3, true));
  c.primitives.push_back(Part("b/0", 1, 5, 4, 2, true));
  c.primitives.push_back(Part("a/1", 0, 3, 8, 3, true));   // 8 influences: the mesh takes 8
  c.primitives.push_back(Part("c/0", 0, 6, 4, 3, false));  // no normals: a mesh of its own
  return c;
}

TEST(CharacterMeshesTest, OneMeshPerSkinInOrderOfFirstPrimitiveNormalsKeptApart) {
  const Character c = Make();
  auto meshes = CharacterMeshes(c);
  ASSERT_TRUE(meshes.ok()) << meshes.status().ToString();
  ASSERT_EQ(meshes->size(), 3u);
  const CharacterMesh& body = (*meshes)[0];
  EXPECT_EQ(body.skin, 0);
  EXPECT_EQ(body.name, "Body (normals)");
  ASSERT_EQ(body.parts.size(), 2u);
  EXPECT_EQ(body.parts[0].primitive, 0);
  EXPECT_EQ(body.parts[1].primitive, 2);
  EXPECT_EQ(body.parts[1].first_vertex, 4u);
  EXPECT_EQ(body.arrays.vertex_count, 7u);
  EXPECT_EQ(body.arrays.influences, 8u);
  EXPECT_EQ(body.arrays.joint_count, 3u);
  EXPECT_EQ(body.arrays.normals.size(), 21u);
  // Primitive 0's 4 influences, padded with weight 0 and joint 0 to 8.
  for (uint32_t i = 0; i < 8; ++i) {
    EXPECT_EQ(body.arrays.joints[8 + i], i < 4 ? c.primitives[0].arrays.joints[4 + i] : 0) << i;
    EXPECT_EQ(body.arrays.weights[8 + i], i < 4 ? c.primitives[0].arrays.weights[4 + i] : 0) << i;
  }
  // Primitive 2's as they are, and its triangles renumbered past primitive 0's vertices.
  for (uint32_t i = 0; i < 8; ++i)
    EXPECT_EQ(body.arrays.joints[32 + i], c.primitives[2].arrays.joints[i]);
  ASSERT_EQ(body.indices.size(), 6u + 3u);
  EXPECT_EQ(body.indices[6], 4u);
  EXPECT_EQ(body.indices[8], 6u);
  EXPECT_EQ(body.parts[1].first_index, 6u);
  // Mesh validation accepts the result.
  EXPECT_TRUE(Mesh::Create(body.arrays).ok());

  EXPECT_EQ((*meshes)[1].skin, 1);
  EXPECT_EQ((*meshes)[1].name, "skins[1]");
  EXPECT_EQ((*meshes)[2].skin, 0);
  EXPECT_EQ((*meshes)[2].name, "Body (no normals)");
  EXPECT_TRUE((*meshes)[2].arrays.normals.empty());
  EXPECT_TRUE(Mesh::Create((*meshes)[2].arrays).ok());
}

TEST(CharacterMeshesTest, OnePrimitiveAloneAndOutOfRange) {
  const Character c = Make();
  auto one = CharacterMeshes(c, 2);
  ASSERT_TRUE(one.ok()) << one.status().ToString();
  ASSERT_EQ(one->size(), 1u);
  EXPECT_EQ((*one)[0].name, "Body");
  ASSERT_EQ((*one)[0].parts.size(), 1u);
  EXPECT_EQ((*one)[0].parts[0].primitive, 2);
  EXPECT_EQ((*one)[0].arrays.positions, c.primitives[2].arrays.positions);
  EXPECT_EQ((*one)[0].indices, c.primitives[2].indices);

  auto bad = CharacterMeshes(c, 4);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(bad.status().message(), "primitive 4 is not below the 4 primitive(s)");
}

// A rigid part: skin -1, one influence (joint 0, weight 1), following `node`.
SkinnedPrimitive RigidPart(const std::string& name, int node, uint32_t vertices, bool normals) {
  SkinnedPrimitive p = Part(name, 0, vertices, 1, 1, normals);
  p.skin = -1;
  p.node = node;
  return p;
}

TEST(CharacterMeshesTest, RigidPartsJoinTheFirstSkinEachNodeOneEntryPastItsJoints) {
  Character c = Make();
  c.nodes.resize(9);
  c.primitives.insert(c.primitives.begin(), RigidPart("r/0", 7, 3, true));  // before any skin
  c.primitives.push_back(RigidPart("s/0", 8, 4, true));
  c.primitives.push_back(RigidPart("r/1", 7, 5, false));
  auto meshes = CharacterMeshes(c);
  ASSERT_TRUE(meshes.ok()) << meshes.status().ToString();
  // Skin 0 (first skinned primitive a/0) with normals: r/0, a/0, a/1, s/0; skin 1: b/0;
  // skin 0 without normals: c/0, r/1.
  ASSERT_EQ(meshes->size(), 3u);
  const CharacterMesh& body = (*meshes)[0];
  EXPECT_EQ(body.skin, 0);
  EXPECT_EQ(body.rigid_nodes, (std::vector<int>{7, 8}));
  EXPECT_EQ(body.arrays.joint_count, 5u);  // 3 joints + 2 nodes
  ASSERT_EQ(body.parts.size(), 4u);
  EXPECT_EQ(body.parts[0].name, "r/0");
  EXPECT_EQ(body.parts[3].name, "s/0");
  const std::size_t b = body.arrays.influences;  // 8: a/1's
  for (const PrimitiveSpan& part : {body.parts[0], body.parts[3]}) {
    const uint16_t joint = part.name == "r/0" ? 3 : 4;
    for (uint32_t v = part.first_vertex; v < part.first_vertex + part.vertex_count; ++v) {
      EXPECT_EQ(body.arrays.joints[v * b], joint) << part.name;
      EXPECT_EQ(body.arrays.weights[v * b], 1.0f) << part.name;
      for (std::size_t i = 1; i < b; ++i) EXPECT_EQ(body.arrays.weights[v * b + i], 0.0f);
    }
  }
  EXPECT_TRUE(Mesh::Create(body.arrays).ok());
  const CharacterMesh& plain = (*meshes)[2];
  EXPECT_EQ(plain.rigid_nodes, (std::vector<int>{7}));
  EXPECT_EQ(plain.arrays.joint_count, 4u);

  // A rigid part alone: a mesh of its own with no skin, its node the only entry.
  auto alone = CharacterMeshes(c, 0);
  ASSERT_TRUE(alone.ok()) << alone.status().ToString();
  ASSERT_EQ(alone->size(), 1u);
  EXPECT_EQ((*alone)[0].skin, -1);
  EXPECT_EQ((*alone)[0].name, "rigid parts");
  EXPECT_EQ((*alone)[0].rigid_nodes, (std::vector<int>{7}));
  EXPECT_EQ((*alone)[0].arrays.joint_count, 1u);
}

}  // namespace
}  // namespace skinserve::testing
