// Morph targets in the data model: sparse targets are kept as given, charged in the mesh's
// bytes and its content id, and every bad target or frame weight gets INVALID_ARGUMENT or
// RESOURCE_EXHAUSTED naming the field, the target, the delta and the limit.
#include "skinserve/model/morph_targets.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "expect_status.h"
#include "skinserve/model/mesh.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve {
namespace {

using testing::ExpectStatus;

// 10 vertices in a unit-ish box; target 0 moves vertices 1 and 4, target 1 vertex 9.
MeshArrays MorphMesh() {
  MeshArrays a = MakeSyntheticMesh(
      {.vertex_count = 10, .influences = 2, .joint_count = 4, .normals = true, .seed = 3});
  a.morph_target_sizes = {2, 1};
  a.morph_indices = {1, 4, 9};
  a.morph_position_deltas = {0.1f, 0, 0, 0, 0.2f, 0, 0, 0, -0.3f};
  a.morph_normal_deltas = {0, 0.1f, 0, 0, 0, 0, 0.2f, 0, 0};
  return a;
}

void ExpectError(const MeshArrays& arrays, StatusCode code, const std::string& needle,
                 const MeshOptions& options = {}) {
  auto mesh = Mesh::Create(arrays, options);
  ASSERT_FALSE(mesh.ok()) << "expected an error containing '" << needle << "'";
  ExpectStatus(mesh.status(), code, needle);
}

TEST(MorphTargetsTest, KeepsSparseTargetsAndChargesThem) {
  const MeshArrays arrays = MorphMesh();
  auto mesh = Mesh::Create(arrays);
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  EXPECT_EQ((*mesh)->morph_target_count(), 2u);
  EXPECT_TRUE((*mesh)->has_morph_normals());
  EXPECT_EQ(std::vector<uint32_t>((*mesh)->morph_offsets().begin(), (*mesh)->morph_offsets().end()),
            (std::vector<uint32_t>{0, 2, 3}));
  EXPECT_EQ(std::vector<uint32_t>((*mesh)->morph_indices().begin(), (*mesh)->morph_indices().end()),
            arrays.morph_indices);
  EXPECT_EQ(std::vector<float>((*mesh)->morph_position_deltas().begin(),
                               (*mesh)->morph_position_deltas().end()),
            arrays.morph_position_deltas);
  // 10 vertices * (24 + 2 * 6) bytes, 3 deltas * (4 + 24) bytes, 3 offsets * 4 bytes.
  EXPECT_EQ((*mesh)->byte_size(), 10u * 36 + 3 * 28 + 3 * 4);

  MeshArrays plain = arrays;
  plain.morph_target_sizes.clear();
  plain.morph_indices.clear();
  plain.morph_position_deltas.clear();
  plain.morph_normal_deltas.clear();
  auto without = Mesh::Create(plain);
  ASSERT_TRUE(without.ok());
  EXPECT_NE((*mesh)->id(), (*without)->id()) << "targets are part of the content";
  MeshArrays other = arrays;
  other.morph_position_deltas[0] = 0.11f;
  auto changed = Mesh::Create(other);
  ASSERT_TRUE(changed.ok());
  EXPECT_NE((*mesh)->id(), (*changed)->id());
}

TEST(MorphTargetsTest, RejectsIndicesOutOfRangeOrNotAscending) {
  MeshArrays a = MorphMesh();
  a.morph_indices = {1, 4, 10};
  ExpectError(a, StatusCode::kInvalidArgument,
              "morph_indices[target 1, delta 0] = 10 is not below vertex_count 10");
  a = MorphMesh();
  a.morph_indices = {4, 4, 9};
  ExpectError(a, StatusCode::kInvalidArgument,
              "morph_indices[target 0, delta 1] = 4 does not ascend");
  a = MorphMesh();
  a.morph_indices = {4, 1, 9};
  ExpectError(a, StatusCode::kInvalidArgument,
              "morph_indices[target 0, delta 1] = 1 does not ascend");
}

TEST(MorphTargetsTest, RejectsNonFiniteAndOutOfRangeDeltas) {
  MeshArrays a = MorphMesh();
  a.morph_position_deltas[4] = std::numeric_limits<float>::quiet_NaN();
  ExpectError(a, StatusCode::kInvalidArgument, "morph_position_deltas[target 0, delta 1].y = nan");
  a = MorphMesh();
  a.morph_position_deltas[8] = 1e6f;  // the mesh spans a few units: 16 x that is far less
  ExpectError(
      a, StatusCode::kInvalidArgument,
      "morph_position_deltas[target 1, delta 0].z = 1000000 must be finite and within +-16");
  a = MorphMesh();
  a.morph_normal_deltas[6] = 5.0f;
  ExpectError(a, StatusCode::kInvalidArgument,
              "morph_normal_deltas[target 1, delta 0].x = 5 must be finite and within +-4");
  a = MorphMesh();
  a.morph_normal_deltas[0] = std::numeric_limits<float>::infinity();
  ExpectError(a, StatusCode::kInvalidArgument, "morph_normal_deltas[target 0, delta 0].x = inf");
}

TEST(MorphTargetsTest, RejectsArraysOfTheWrongSizeAndNormalsWithoutNormals) {
  MeshArrays a = MorphMesh();
  a.morph_indices.pop_back();
  ExpectError(a, StatusCode::kInvalidArgument, "morph_indices holds 2 values; expected 3");
  a = MorphMesh();
  a.morph_position_deltas.pop_back();
  ExpectError(a, StatusCode::kInvalidArgument, "morph_position_deltas holds 8 values; expected 9");
  a = MorphMesh();
  a.morph_normal_deltas.resize(3);
  ExpectError(a, StatusCode::kInvalidArgument, "morph_normal_deltas holds 3 values; expected 9");
  a = MorphMesh();
  a.normals.clear();
  ExpectError(a, StatusCode::kInvalidArgument,
              "morph normal deltas were declared but the mesh has no normals");
  a = MorphMesh();
  a.morph_target_sizes = {11, 1};
  ExpectError(a, StatusCode::kInvalidArgument,
              "morph_target_sizes[0] = 11 exceeds vertex_count 10");
}

TEST(MorphTargetsTest, LimitsOnTargetsAndDeltas) {
  MeshArrays a = MorphMesh();
  MeshOptions options;
  options.limits.max_morph_targets = 1;
  ExpectError(a, StatusCode::kResourceExhausted,
              "morph_target_sizes lists 2 targets, over the limit of 1 targets per mesh", options);
  options = {};
  options.limits.max_morph_deltas = 2;
  ExpectError(a, StatusCode::kResourceExhausted,
              "morph targets hold 3 deltas in all, over the limit of 2 deltas per mesh", options);
  // The hard limit holds whatever an operator sets.
  std::vector<uint32_t> sizes(kMaxMorphTargets + 1, 0);
  options = {};
  options.limits.max_morph_targets = 5000;
  EXPECT_EQ(CheckMorphHeader(sizes, 10, true, false, options.limits).code(),
            StatusCode::kResourceExhausted);
  sizes.pop_back();
  EXPECT_TRUE(CheckMorphHeader(sizes, 10, true, false, options.limits).ok());
}

TEST(MorphTargetsTest, FrameWeightsAreCheckedAgainstTheTargets) {
  const MorphWeight good[] = {{3, 0.5f}, {0, -1.2f}, {7, 2.0f}};
  EXPECT_TRUE(ValidateMorphWeights(good, 8).ok());
  EXPECT_TRUE(ValidateMorphWeights({}, 0).ok());
  auto expect = [](std::span<const MorphWeight> w, uint32_t targets, const std::string& needle) {
    ExpectStatus(ValidateMorphWeights(w, targets), StatusCode::kInvalidArgument, needle);
  };
  const MorphWeight missing[] = {{0, 1}, {8, 1}};
  expect(missing, 8, "morph_weights[1]: target 8 is not below the mesh's morph_target_count 8");
  const MorphWeight twice[] = {{2, 1}, {5, 1}, {2, 0.5f}};
  expect(twice, 8, "morph_weights[2]: target 2 is listed twice");
  const MorphWeight nan[] = {{1, std::numeric_limits<float>::quiet_NaN()}};
  expect(nan, 8, "morph_weights[0]: weight nan of target 1 must be finite and within +-100");
  const MorphWeight inf[] = {{1, -std::numeric_limits<float>::infinity()}};
  expect(inf, 8, "weight -inf of target 1");
  const MorphWeight big[] = {{1, 100.5f}};
  expect(big, 8, "weight 100.5 of target 1");
  EXPECT_FALSE(HasActiveMorph({}));
  const MorphWeight zero[] = {{1, 0.0f}, {2, -0.0f}};
  EXPECT_FALSE(HasActiveMorph(zero));
  EXPECT_TRUE(HasActiveMorph(good));
}

}  // namespace
}  // namespace skinserve
