#include "skinserve/reference/synthetic.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "skinserve/model/mesh.h"
#include "skinserve/model/palette.h"

namespace skinserve {
namespace {

TEST(SyntheticTest, MeshIsValidAndDeterministicFromTheSeed) {
  const SyntheticMeshSpec spec{.vertex_count = 2000, .influences = 4, .normals = true, .seed = 3};
  const MeshArrays a = MakeSyntheticMesh(spec);
  const MeshArrays b = MakeSyntheticMesh(spec);
  EXPECT_EQ(a.positions, b.positions);
  EXPECT_EQ(a.joints, b.joints);
  EXPECT_EQ(a.weights, b.weights);
  EXPECT_EQ(a.joint_count, 77u);
  auto mesh = Mesh::Create(a);
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  EXPECT_EQ((*mesh)->normalized_vertices(), 0u);

  SyntheticMeshSpec other = spec;
  other.seed = 4;
  EXPECT_NE(MakeSyntheticMesh(other).positions, a.positions);
}

// Sorted by joints: the same vertices (each one's position, normal, tangent, joints and
// weights kept together), ordered by their joint lists.
TEST(SyntheticTest, SortedByJointsIsThePermutationOrderedByJoints) {
  SyntheticMeshSpec spec{
      .vertex_count = 3000, .influences = 3, .normals = true, .tangents = true, .seed = 9};
  const MeshArrays shuffled = MakeSyntheticMesh(spec);
  spec.sorted_by_joints = true;
  const MeshArrays sorted = MakeSyntheticMesh(spec);
  ASSERT_EQ(sorted.vertex_count, shuffled.vertex_count);
  // Each vertex as one record; the multisets must match and the sorted joints ascend.
  auto record = [](const MeshArrays& m, uint32_t v) {
    std::vector<float> r(m.positions.begin() + 3 * v, m.positions.begin() + 3 * v + 3);
    r.insert(r.end(), m.normals.begin() + 3 * v, m.normals.begin() + 3 * v + 3);
    r.insert(r.end(), m.tangents.begin() + 4 * v, m.tangents.begin() + 4 * v + 4);
    for (uint32_t i = 0; i < m.influences; ++i) {
      r.push_back(static_cast<float>(m.joints[m.influences * v + i]));
      r.push_back(m.weights[m.influences * v + i]);
    }
    return r;
  };
  std::vector<std::vector<float>> a, b;
  for (uint32_t v = 0; v < shuffled.vertex_count; ++v) {
    a.push_back(record(shuffled, v));
    b.push_back(record(sorted, v));
  }
  EXPECT_NE(a, b);  // the paper's order is not already sorted
  for (uint32_t v = 1; v < sorted.vertex_count; ++v) {
    ASSERT_FALSE(std::lexicographical_compare(
        sorted.joints.begin() + 3 * v, sorted.joints.begin() + 3 * v + 3,
        sorted.joints.begin() + 3 * (v - 1), sorted.joints.begin() + 3 * v))
        << "vertex " << v;
  }
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  EXPECT_EQ(a, b);
}

TEST(SyntheticTest, WeightsAreSmoothNotUniform) {
  const MeshArrays m = MakeSyntheticMesh({.vertex_count = 1000, .influences = 4, .seed = 5});
  int distinct_leading = 0;
  for (uint32_t v = 0; v < m.vertex_count; ++v) {
    const float* w = &m.weights[4 * v];
    // Sorted by distance: the nearest joint weighs most, and weights decay with distance.
    EXPECT_GE(w[0], w[1]);
    EXPECT_GE(w[1], w[2]);
    EXPECT_GE(w[2], w[3]);
    if (w[0] < 0.999f) ++distinct_leading;
  }
  EXPECT_GT(distinct_leading, 500);  // most vertices really blend several joints
}

TEST(SyntheticTest, MoreInfluencesThanJointsArePaddedWithZeroWeight) {
  const MeshArrays m = MakeSyntheticMesh({.vertex_count = 50, .influences = 8, .joint_count = 3});
  for (uint32_t v = 0; v < 50; ++v) {
    for (int i = 3; i < 8; ++i) EXPECT_EQ(m.weights[8 * v + i], 0.0f);
  }
  EXPECT_TRUE(Mesh::Create(m).ok());
}

TEST(SyntheticTest, PaletteIsFiniteDeterministicAndChangesPerFrame) {
  const auto p0 = MakeSyntheticPalette(77, 9, 0);
  EXPECT_TRUE(ValidatePalette(p0, 77).ok());
  EXPECT_EQ(p0, MakeSyntheticPalette(77, 9, 0));
  EXPECT_NE(p0, MakeSyntheticPalette(77, 9, 1));
  // Each 3x3 block is a rotation times a scale in 0.9..1.1: its columns have equal norm.
  for (uint32_t j = 0; j < 77; ++j) {
    const float* m = &p0[12 * j];
    double norms[3];
    for (int c = 0; c < 3; ++c) {
      norms[c] = std::sqrt(m[c] * m[c] + m[4 + c] * m[4 + c] + m[8 + c] * m[8 + c]);
    }
    EXPECT_NEAR(norms[0], norms[1], 1e-5);
    EXPECT_NEAR(norms[1], norms[2], 1e-5);
    EXPECT_GE(norms[0], 0.9 - 1e-6);
    EXPECT_LE(norms[0], 1.1 + 1e-6);
  }
}

TEST(SyntheticTest, IdentityPalette) {
  const auto p = MakeIdentityPalette(2);
  const std::vector<float> expected = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0,
                                       1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
  EXPECT_EQ(p, expected);
}

}  // namespace
}  // namespace skinserve
