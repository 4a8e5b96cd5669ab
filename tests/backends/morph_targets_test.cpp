// Morph targets on every backend: random sparse targets (each vertex in each target with
// probability 0.1 or 0.5, position and normal deltas), random frame weights (negative and
// beyond 1 included, listed in random order), frames with no active target and with only
// zero weights, for both methods each backend implements, B = 1..8 and vertex counts that
// leave vector and thread tails, against the float64 reference that morphs in double
// before skinning (ReferenceMorph, written apart from the engine's morph stage).
// Tolerance: CompareWithReference's with morphs (1e-5 relative to the frame's scale,
// with the morphed terms counted in it; normals 1e-5 times how much the deltas shorten
// them). A backend that does not apply morph targets refuses them: FAILED_PRECONDITION.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <tuple>

#include "backend_fixture.h"
#include "reference_cases.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/reference/synthetic_morph.h"

namespace skinserve::testing {
namespace {

struct MorphCase {
  uint32_t vertices;
  uint32_t influences;
  bool normals;
  double fraction;
};

using MorphBackendCase = std::tuple<std::string, MorphCase>;

std::vector<MorphCase> Cases() {
  std::vector<MorphCase> cases;
  for (uint32_t v : {1u, 7u, 1001u}) {
    for (uint32_t b : {1u, 3u, 4u, 8u}) {
      for (bool n : {false, true}) cases.push_back({v, b, n, 0.1});
    }
  }
  cases.push_back({LargeCaseVertices(), 4, true, 0.1});
  cases.push_back({LargeCaseVertices(), 2, true, 0.5});
  cases.push_back({5003, 4, true, 0.5});
  return cases;
}

std::string Name(const ::testing::TestParamInfo<MorphBackendCase>& info) {
  const auto& [id, c] = info.param;
  std::string name = id + "_V" + std::to_string(c.vertices) + "_B" + std::to_string(c.influences) +
                     (c.normals ? "_normals" : "") + "_F" +
                     std::to_string(static_cast<int>(c.fraction * 100));
  for (char& ch : name) {
    if (ch == '-') ch = '_';
  }
  return name;
}

std::shared_ptr<const Mesh> MorphMesh(const MorphCase& c, uint32_t targets) {
  const uint64_t seed = c.vertices * 31ull + c.influences * 7ull + (c.normals ? 1 : 0);
  MeshArrays arrays = MakeSyntheticMesh({.vertex_count = c.vertices,
                                         .influences = c.influences,
                                         .joint_count = 33,
                                         .normals = c.normals,
                                         .seed = seed});
  AddSyntheticMorphTargets({.targets = targets, .fraction = c.fraction, .seed = seed}, &arrays);
  auto mesh = Mesh::Create(arrays);
  EXPECT_TRUE(mesh.ok()) << mesh.status().ToString();
  return mesh.ok() ? *mesh : nullptr;
}

class MorphTargetsTest : public ::testing::TestWithParam<MorphBackendCase> {};

TEST_P(MorphTargetsTest, MatchesTheFloat64ReferenceOrRefuses) {
  const auto& [id, c] = GetParam();
  Backend& backend = BackendById(id);
  SKIP_IF_UNAVAILABLE(backend);
  constexpr uint32_t kTargets = 24;
  auto mesh = MorphMesh(c, kTargets);
  ASSERT_NE(mesh, nullptr);
  auto prepared = backend.Prepare(mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<float> positions(3ull * c.vertices), normals(c.normals ? 3ull * c.vertices : 0);
  const std::vector<MorphWeight> zeros = {{3, 0.0f}, {5, -0.0f}};
  for (SkinningMethod method : backend.info().methods) {
    for (uint64_t frame = 0; frame < 5; ++frame) {
      // Frames: 4 active, none, only zeros, every target, 1 active.
      std::vector<MorphWeight> weights;
      if (frame == 0) weights = MakeMorphWeights(kTargets, 4, c.vertices, frame);
      if (frame == 2) weights = zeros;
      if (frame == 3) weights = MakeMorphWeights(kTargets, kTargets, c.vertices, frame);
      if (frame == 4) weights = MakeMorphWeights(kTargets, 1, c.vertices, frame);
      const auto palette = method == SkinningMethod::kDualQuaternion
                               ? MakeRigidPalette(33, c.vertices, frame)
                               : MakeSyntheticPalette(33, c.vertices, frame);
      std::fill(positions.begin(), positions.end(), nan);
      std::fill(normals.begin(), normals.end(), nan);
      SkinFrame skin{.palette = palette, .positions = positions, .normals = normals};
      skin.method = method;
      skin.morph_weights = weights;
      ASSERT_TRUE(skin.Validate(*mesh).ok());
      const Status s = backend.Skin(**prepared, skin);
      const std::string what = std::string(MethodName(method)) + " frame " + std::to_string(frame);
      if (!backend.info().morph_targets && HasActiveMorph(weights)) {
        EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition) << what << ": " << s.ToString();
        EXPECT_NE(s.message().find("backend '" + id + "' does not apply morph targets"),
                  std::string::npos)
            << s.message();
        continue;
      }
      ASSERT_TRUE(s.ok()) << id << " " << what << ": " << s.ToString();
      const Deviation d = CompareWithReference(*mesh, palette, positions, normals, method, weights);
      EXPECT_TRUE(d.within_tolerance())
          << id << " " << what << ": position error " << d.max_position_error << " (tolerance "
          << d.position_tolerance << "), normal error " << d.max_normal_error << " (tolerance "
          << d.normal_tolerance << "), worst vertex " << d.worst_vertex;
      if (frame == 3 && c.vertices > 1) {  // the morphs show: without them it is another shape
        EXPECT_FALSE(
            CompareWithReference(*mesh, palette, positions, normals, method, {}).within_tolerance())
            << id << " " << what << " matches the unmorphed reference";
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(AllBackends, MorphTargetsTest,
                         ::testing::Combine(::testing::ValuesIn(ComputingBackendIds()),
                                            ::testing::ValuesIn(Cases())),
                         Name);

// The CPU backends apply morph targets: none may regress to refusing them.
TEST(MorphTargetsSupportTest, CpuBackendsListMorphTargets) {
  for (const char* id : {"serial", "openmp", "sse", "sse-openmp", "simd", "simd-openmp"}) {
    if (!kSseBackendsRunHere && IsSseBackend(id)) continue;
    EXPECT_TRUE(BackendById(id).info().morph_targets) << id;
  }
}

// The reference's morph on a case worked by hand: 0.5 * (0.2, 0, 0) - 2 * (0, 0.1, 0).
TEST(MorphReferenceTest, AddsWeightedDeltasInDouble) {
  MeshArrays arrays{.vertex_count = 2,
                    .influences = 1,
                    .joint_count = 1,
                    .positions = {1, 2, 3, 4, 5, 6},
                    .normals = {0, 0, 1, 0, 1, 0},
                    .joints = {0, 0},
                    .weights = {1, 1},
                    .morph_target_sizes = {1, 2},
                    .morph_indices = {1, 0, 1},
                    .morph_position_deltas = {0.2f, 0, 0, 0, 0, 1, 0, 0.1f, 0},
                    .morph_normal_deltas = {0, 0, 0, 1, 0, 0, 0, 0, 0}};
  auto mesh = Mesh::Create(arrays);
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  const MorphWeight weights[] = {{0, 0.5f}, {1, -2.0f}};
  const ReferenceFrame rest = ReferenceMorph(**mesh, weights);
  EXPECT_NEAR(rest.positions[0], 1, 1e-12);
  EXPECT_NEAR(rest.positions[2], 3 - 2, 1e-12);
  EXPECT_NEAR(rest.positions[3], 4 + 0.5 * double{0.2f}, 1e-12);
  EXPECT_NEAR(rest.positions[4], 5 - 2 * double{0.1f}, 1e-12);
  EXPECT_NEAR(rest.normals[0], -2, 1e-12);
  // Skinned with the identity, the positions are the morphed rest.
  const std::vector<float> identity = MakeIdentityPalette(1);
  const ReferenceFrame skinned = ReferenceSkin(**mesh, identity, weights);
  EXPECT_NEAR(skinned.positions[4], 5 - 2 * double{0.1f}, 1e-12);
  const double length = std::sqrt(4.0 + 1.0);  // normal (-2, 0, 1) renormalised
  EXPECT_NEAR(skinned.normals[0], -2 / length, 1e-12);
}

}  // namespace
}  // namespace skinserve::testing
