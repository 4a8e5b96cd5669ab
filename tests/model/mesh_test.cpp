// Mesh validation: every bad input gets INVALID_ARGUMENT or RESOURCE_EXHAUSTED with a
// message that names the field, the index and the limit.
#include "skinserve/model/mesh.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "expect_status.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve {
namespace {

using testing::ExpectStatus;

MeshArrays SmallMesh(bool normals = true) {
  return MakeSyntheticMesh(
      {.vertex_count = 10, .influences = 3, .joint_count = 5, .normals = normals, .seed = 7});
}

void ExpectError(const MeshArrays& arrays, StatusCode code, const std::string& needle,
                 const MeshOptions& options = {}) {
  auto mesh = Mesh::Create(arrays, options);
  ASSERT_FALSE(mesh.ok()) << "expected an error containing '" << needle << "'";
  ExpectStatus(mesh.status(), code, needle);
}

TEST(MeshTest, AcceptsValidMeshAndKeepsItsData) {
  const MeshArrays arrays = SmallMesh();
  auto mesh = Mesh::Create(arrays);
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  EXPECT_EQ((*mesh)->vertex_count(), 10u);
  EXPECT_EQ((*mesh)->influences(), 3u);
  EXPECT_EQ((*mesh)->joint_count(), 5u);
  EXPECT_TRUE((*mesh)->has_normals());
  EXPECT_EQ(std::vector<float>((*mesh)->positions().begin(), (*mesh)->positions().end()),
            arrays.positions);
  EXPECT_EQ(std::vector<uint16_t>((*mesh)->joints().begin(), (*mesh)->joints().end()),
            arrays.joints);
  EXPECT_EQ(reinterpret_cast<uintptr_t>((*mesh)->positions().data()) % 64, 0u);
  EXPECT_EQ(reinterpret_cast<uintptr_t>((*mesh)->weights().data()) % 64, 0u);
  EXPECT_EQ((*mesh)->byte_size(), 10u * (24 + 3 * 6));
}

TEST(MeshTest, IdIsAContentHash) {
  auto a = Mesh::Create(SmallMesh());
  auto b = Mesh::Create(SmallMesh());
  MeshArrays moved = SmallMesh();
  moved.positions[4] += 0.5f;
  auto c = Mesh::Create(moved);
  ASSERT_TRUE(a.ok() && b.ok() && c.ok());
  EXPECT_EQ((*a)->id().size(), 64u);  // SHA-256 in hex
  EXPECT_EQ((*a)->id(), (*b)->id());
  EXPECT_NE((*a)->id(), (*c)->id());
  auto d = Mesh::Create(SmallMesh(/*normals=*/false));
  ASSERT_TRUE(d.ok());
  EXPECT_NE((*a)->id(), (*d)->id());
}

TEST(MeshTest, RejectsZeroVertices) {
  MeshArrays m;
  m.influences = 1;
  m.joint_count = 1;
  ExpectError(m, StatusCode::kInvalidArgument, "vertex_count is 0");
}

TEST(MeshTest, RejectsTooManyVerticesBeforeLookingAtArrays) {
  MeshArrays m = SmallMesh();
  m.vertex_count = 5'000'000;
  ExpectError(m, StatusCode::kResourceExhausted,
              "vertex_count 5000000 exceeds the limit of 4000000");
}

TEST(MeshTest, RejectsInfluencesOutside1To8) {
  for (uint32_t b : {0u, 9u}) {
    MeshArrays m = SmallMesh();
    m.influences = b;
    ExpectError(m, StatusCode::kInvalidArgument,
                "influences is " + std::to_string(b) + "; it must be 1..8");
  }
}

TEST(MeshTest, RejectsJointCountZeroOrOverLimit) {
  MeshArrays m = SmallMesh();
  m.joint_count = 0;
  ExpectError(m, StatusCode::kInvalidArgument, "joint_count is 0");
  m.joint_count = 2000;
  ExpectError(m, StatusCode::kResourceExhausted, "joint_count 2000 exceeds the limit of 1024");
  m.joint_count = 70000;
  ExpectError(m, StatusCode::kInvalidArgument, "joint_count 70000 exceeds 65535");
}

TEST(MeshTest, RejectsArraysOfTheWrongSize) {
  MeshArrays m = SmallMesh();
  m.positions.pop_back();
  ExpectError(m, StatusCode::kInvalidArgument, "positions holds 29 values; expected 30");
  m = SmallMesh();
  m.normals.resize(3);
  ExpectError(m, StatusCode::kInvalidArgument, "normals holds 3 values; expected 30");
  m = SmallMesh();
  m.joints.pop_back();
  ExpectError(m, StatusCode::kInvalidArgument, "joints holds 29 values; expected 30");
  m = SmallMesh();
  m.weights.push_back(0);
  ExpectError(m, StatusCode::kInvalidArgument, "weights holds 31 values; expected 30");
}

TEST(MeshTest, RejectsJointIndexAtOrPastJointCount) {
  MeshArrays m = SmallMesh();
  m.joints[3 * 4 + 2] = 5;  // vertex 4, influence 2; joint_count is 5
  ExpectError(m, StatusCode::kInvalidArgument,
              "joints[vertex 4, influence 2] = 5 is not below joint_count 5");
}

TEST(MeshTest, RejectsNonFinitePositionsAndNormals) {
  MeshArrays m = SmallMesh();
  m.positions[3 * 6 + 1] = std::numeric_limits<float>::quiet_NaN();
  ExpectError(m, StatusCode::kInvalidArgument, "positions[vertex 6].y = nan is not finite");
  m = SmallMesh();
  m.normals[3 * 2 + 2] = std::numeric_limits<float>::infinity();
  ExpectError(m, StatusCode::kInvalidArgument, "normals[vertex 2].z = inf is not finite");
  m = SmallMesh();
  m.normals[9] = m.normals[10] = m.normals[11] = 0.0f;
  ExpectError(m, StatusCode::kInvalidArgument, "normals[vertex 3] is the zero vector");
}

MeshArrays TangentMesh() {
  return MakeSyntheticMesh({.vertex_count = 10,
                            .influences = 3,
                            .joint_count = 5,
                            .normals = true,
                            .tangents = true,
                            .seed = 7});
}

TEST(MeshTest, KeepsTangentsAndCountsThemInTheIdAndSize) {
  const MeshArrays arrays = TangentMesh();
  auto mesh = Mesh::Create(arrays);
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  EXPECT_TRUE((*mesh)->has_tangents());
  EXPECT_EQ(std::vector<float>((*mesh)->tangents().begin(), (*mesh)->tangents().end()),
            arrays.tangents);
  EXPECT_EQ((*mesh)->byte_size(), 10u * (24 + 16 + 3 * 6));
  auto without = Mesh::Create(SmallMesh());  // the same mesh without tangents
  ASSERT_TRUE(without.ok());
  EXPECT_NE((*mesh)->id(), (*without)->id());
  MeshArrays flipped = arrays;
  flipped.tangents[3] = -flipped.tangents[3];  // the handedness is content too
  auto other = Mesh::Create(flipped);
  ASSERT_TRUE(other.ok()) << other.status().ToString();
  EXPECT_NE((*mesh)->id(), (*other)->id());
}

TEST(MeshTest, RejectsBadTangentsNamingTheFieldAndTheLimit) {
  MeshArrays arrays = TangentMesh();
  arrays.tangents.pop_back();
  ExpectError(arrays, StatusCode::kInvalidArgument,
              "tangents holds 39 values; expected 40 = 4 * vertex_count");
  arrays = TangentMesh();
  arrays.tangents[4 * 2 + 1] = std::numeric_limits<float>::quiet_NaN();
  ExpectError(arrays, StatusCode::kInvalidArgument, "tangents[vertex 2].y = nan is not finite");
  arrays = TangentMesh();
  for (int a = 0; a < 3; ++a) arrays.tangents[4 * 3 + a] *= 1.1f;
  ExpectError(arrays, StatusCode::kInvalidArgument, "tangents[vertex 3].xyz has length 1.1");
  ExpectError(arrays, StatusCode::kInvalidArgument, "must be a unit vector within 0.01");
  arrays = TangentMesh();
  arrays.tangents[4 * 4 + 3] = 0.5f;
  ExpectError(arrays, StatusCode::kInvalidArgument,
              "tangents[vertex 4].w = 0.5; it must be exactly +1 or -1");
  arrays = TangentMesh();
  arrays.normals.clear();
  ExpectError(arrays, StatusCode::kInvalidArgument, "tangents need normals");
  // Rounding within the tolerance (an 8-bit exporter's) is accepted.
  arrays = TangentMesh();
  for (int a = 0; a < 3; ++a) arrays.tangents[4 * 5 + a] *= 1.005f;
  EXPECT_TRUE(Mesh::Create(arrays).ok());
}

TEST(MeshTest, RejectsTangentDeltasWithoutTangentsOrOutOfRange) {
  MeshArrays arrays = TangentMesh();
  arrays.morph_target_sizes = {2};
  arrays.morph_indices = {1, 4};
  arrays.morph_position_deltas = {0, 0, 0, 0, 0.1f, 0};
  arrays.morph_tangent_deltas = {0, 0, 0, 0, 0.5f, 0};
  ASSERT_TRUE(Mesh::Create(arrays).ok());
  EXPECT_TRUE((*Mesh::Create(arrays))->has_morph_tangents());
  MeshArrays bad = arrays;
  bad.morph_tangent_deltas[4] = 5.0f;
  ExpectError(bad, StatusCode::kInvalidArgument,
              "morph_tangent_deltas[target 0, delta 1].y = 5 must be finite and within +-4");
  bad = arrays;
  bad.morph_tangent_deltas.pop_back();
  ExpectError(bad, StatusCode::kInvalidArgument, "morph_tangent_deltas holds 5 values");
  bad = arrays;
  bad.tangents.clear();
  ExpectError(bad, StatusCode::kInvalidArgument,
              "morph tangent deltas were declared but the mesh has no tangents");
}

TEST(MeshTest, RejectsNegativeNonFiniteOrAllZeroWeights) {
  MeshArrays m = SmallMesh();
  m.weights[3 * 1 + 1] = -0.25f;
  ExpectError(m, StatusCode::kInvalidArgument, "weights[vertex 1, influence 1] = -0.25");
  m = SmallMesh();
  m.weights[3 * 1 + 1] = std::numeric_limits<float>::quiet_NaN();
  ExpectError(m, StatusCode::kInvalidArgument, "weights[vertex 1, influence 1] = nan");
  m = SmallMesh();
  m.weights[6] = m.weights[7] = m.weights[8] = 0.0f;
  ExpectError(m, StatusCode::kInvalidArgument, "weights[vertex 2] are all zero");
}

TEST(MeshTest, WeightSumsBeyondToleranceAreRejectedOrNormalisedAsAsked) {
  MeshArrays m = SmallMesh();
  for (int i = 0; i < 3; ++i) m.weights[3 * 8 + i] *= 2.0f;  // vertex 8 sums to 2
  ExpectError(m, StatusCode::kInvalidArgument, "weights[vertex 8] sum to 2");

  auto mesh = Mesh::Create(m, {.weight_policy = WeightPolicy::kNormalize});
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  EXPECT_EQ((*mesh)->normalized_vertices(), 1u);
  for (uint32_t v = 0; v < 10; ++v) {
    double sum = 0;
    for (int i = 0; i < 3; ++i) sum += (*mesh)->weights()[3 * v + i];
    EXPECT_NEAR(sum, 1.0, 1e-6) << "vertex " << v;
  }
  // Normalised vertex 8 equals the original weights.
  const MeshArrays original = SmallMesh();
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR((*mesh)->weights()[3 * 8 + i], original.weights[3 * 8 + i], 1e-6);
  }
}

TEST(MeshTest, SmallRoundingInWeightSumsIsAccepted) {
  MeshArrays m = SmallMesh();
  m.weights[0] += 5e-4f;
  auto mesh = Mesh::Create(m);
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  EXPECT_EQ((*mesh)->normalized_vertices(), 0u);
}

TEST(MeshTest, HeaderCheckNeedsNoArrays) {
  EXPECT_TRUE(CheckMeshHeader(1'600'000, 4, 77, {}).ok());
  EXPECT_EQ(CheckMeshHeader(1'600'000, 4, 77, {.max_vertices = 1000}).code(),
            StatusCode::kResourceExhausted);
  EXPECT_EQ(MeshByteSize(1'600'000, 4, false), 1'600'000ull * (12 + 4 * 6));
}

}  // namespace
}  // namespace skinserve
