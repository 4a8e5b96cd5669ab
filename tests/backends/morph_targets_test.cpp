// Morph targets on every backend: random sparse targets (each vertex in each target with
// probability 0.1 or 0.5, position, normal and tangent deltas), random frame weights (negative and
// beyond 1 included, listed in random order), frames with no active target and with only
// zero weights, for both methods each backend implements, B = 1..8 and vertex counts that
// leave vector and thread tails, against the float64 reference that morphs in double
// before skinning (ReferenceMorph, written apart from the engine's morph stage).
// Tolerance: CompareWithReference's with morphs (1e-5 relative to the frame's scale,
// with the morphed terms counted in it; normals 1e-5 times how much the deltas shorten
// them; tangents' xyz the same, their w exact). A backend that does not apply morph targets
// refuses them, one that does not skin tangents refuses those: FAILED_PRECONDITION.
// Every computing backend applies them, the OpenCL ones on the device (morph_targets.cl);
// beyond the grid: frames after a morphed frame that have no active target come back
// unmorphed (no morphed rest arrays left behind, on the device or in a thread's scratch),
// targets that all move every vertex, and hundreds of targets with hundreds active.
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
  bool tangents = false;  // with normals only
};

using MorphBackendCase = std::tuple<std::string, MorphCase>;

std::vector<MorphCase> Cases() {
  std::vector<MorphCase> cases;
  for (uint32_t v : {1u, 7u, 1001u}) {
    for (uint32_t b : {1u, 3u, 4u, 8u}) {
      cases.push_back({v, b, false, 0.1});
      cases.push_back({v, b, true, 0.1});
      cases.push_back({v, b, true, 0.1, true});
    }
  }
  cases.push_back({LargeCaseVertices(), 4, true, 0.1, true});
  cases.push_back({LargeCaseVertices(), 2, true, 0.5});
  cases.push_back({5003, 4, true, 0.5});
  return cases;
}

std::string Name(const ::testing::TestParamInfo<MorphBackendCase>& info) {
  const auto& [id, c] = info.param;
  std::string name = id + "_V" + std::to_string(c.vertices) + "_B" + std::to_string(c.influences) +
                     (c.normals ? "_normals" : "") + "_F" +
                     std::to_string(static_cast<int>(c.fraction * 100)) +
                     (c.tangents ? "_tangents" : "");
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
                                         .tangents = c.tangents,
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
  std::vector<float> tangents(c.tangents ? 4ull * c.vertices : 0);
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
      std::fill(tangents.begin(), tangents.end(), nan);
      SkinFrame skin{
          .palette = palette, .positions = positions, .normals = normals, .tangents = tangents};
      skin.method = method;
      skin.morph_weights = weights;
      ASSERT_TRUE(skin.Validate(*mesh).ok());
      const Status s = backend.Skin(**prepared, skin);
      const std::string what = std::string(MethodName(method)) + " frame " + std::to_string(frame);
      if (c.tangents && !backend.info().tangents) {
        EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition) << what << ": " << s.ToString();
        EXPECT_NE(s.message().find("backend '" + id + "' does not skin tangents"),
                  std::string::npos)
            << s.message();
        continue;
      }
      if (!backend.info().morph_targets && HasActiveMorph(weights)) {
        EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition) << what << ": " << s.ToString();
        EXPECT_NE(s.message().find("backend '" + id + "' does not apply morph targets"),
                  std::string::npos)
            << s.message();
        continue;
      }
      ASSERT_TRUE(s.ok()) << id << " " << what << ": " << s.ToString();
      const Deviation d =
          CompareWithReference(*mesh, palette, positions, normals, method, weights, tangents);
      EXPECT_TRUE(d.within_tolerance())
          << id << " " << what << ": position error " << d.max_position_error << " (tolerance "
          << d.position_tolerance << "), normal error " << d.max_normal_error << " (tolerance "
          << d.normal_tolerance << "), tangent error " << d.max_tangent_error << " (tolerance "
          << d.tangent_tolerance << "), worst vertex " << d.worst_vertex;
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

// Every computing backend applies morph targets (the OpenCL ones where OpenCL runs): none
// may regress to refusing them.
TEST(MorphTargetsSupportTest, ComputingBackendsListMorphTargets) {
  for (const char* id : {"serial", "openmp", "sse", "sse-openmp", "simd", "simd-openmp", "opencl",
                         "opencl-zerocopy"}) {
    if (!kSseBackendsRunHere && IsSseBackend(id)) continue;
    const Backend& backend = BackendById(id);
    if (!backend.info().available) continue;  // listed unavailable, with the reason
    EXPECT_TRUE(backend.info().morph_targets) << id;
  }
  EXPECT_FALSE(BackendById("passthrough").info().morph_targets);
}

std::string BackendName(const ::testing::TestParamInfo<std::string>& info) {
  std::string name = info.param;
  for (char& ch : name) {
    if (ch == '-') ch = '_';
  }
  return name;
}

// One frame of `weights` into NaN-filled outputs, checked against the reference; with
// `unmorphed_differs`, also checked to differ from the unmorphed reference (the morph shows).
void ExpectMorphedFrame(Backend& backend, const PreparedMesh& prepared, SkinningMethod method,
                        bool normals, std::span<const MorphWeight> weights, uint64_t frame,
                        bool unmorphed_differs, const std::string& what) {
  const Mesh& mesh = prepared.mesh();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<float> positions(3ull * mesh.vertex_count(), nan);
  std::vector<float> out_normals(normals ? 3ull * mesh.vertex_count() : 0, nan);
  // Tangents with the normals wherever the mesh has them and the backend skins them.
  const bool tangents = normals && mesh.has_tangents() && backend.info().tangents;
  std::vector<float> out_tangents(tangents ? 4ull * mesh.vertex_count() : 0, nan);
  const auto palette = method == SkinningMethod::kDualQuaternion
                           ? MakeRigidPalette(mesh.joint_count(), 17, frame)
                           : MakeSyntheticPalette(mesh.joint_count(), 17, frame);
  SkinFrame skin{
      .palette = palette, .positions = positions, .normals = out_normals, .tangents = out_tangents};
  skin.method = method;
  skin.morph_weights = weights;
  ASSERT_TRUE(skin.Validate(mesh).ok());
  const std::string where = backend.info().id + " " + std::string(MethodName(method)) + " " + what;
  const Status s = backend.Skin(prepared, skin);
  ASSERT_TRUE(s.ok()) << where << ": " << s.ToString();
  const Deviation d =
      CompareWithReference(mesh, palette, positions, out_normals, method, weights, out_tangents);
  EXPECT_TRUE(d.within_tolerance())
      << where << ": position error " << d.max_position_error << " (tolerance "
      << d.position_tolerance << "), normal error " << d.max_normal_error << " (tolerance "
      << d.normal_tolerance << "), tangent error " << d.max_tangent_error << " (tolerance "
      << d.tangent_tolerance << "), worst vertex " << d.worst_vertex;
  if (unmorphed_differs) {
    EXPECT_FALSE(
        CompareWithReference(mesh, palette, positions, out_normals, method, {}).within_tolerance())
        << where << " matches the unmorphed reference";
  }
}

class MorphFrameSequenceTest : public ::testing::TestWithParam<std::string> {};

// Frames on one prepared mesh whose 12 targets each move every vertex (so every vertex sums
// many targets' deltas): morphed frames alternate with frames that have no weights or only
// zero weights, with and without normals, in both methods. Each frame must match its own
// reference: a frame without an active target skins the rest arrays, whatever the frame
// before it left in the backend's morphed buffers.
TEST_P(MorphFrameSequenceTest, FramesWithoutActiveTargetsAfterMorphedOnesAreUnmorphed) {
  Backend& backend = BackendById(GetParam());
  SKIP_IF_UNAVAILABLE(backend);
  constexpr uint32_t kTargets = 12;
  auto mesh = MorphMesh(
      {.vertices = 5003, .influences = 4, .normals = true, .fraction = 1.0, .tangents = true},
      kTargets);
  ASSERT_NE(mesh, nullptr);
  auto prepared = backend.Prepare(mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  const std::vector<MorphWeight> zeros = {{1, 0.0f}, {7, 0.0f}};
  for (SkinningMethod method : backend.info().methods) {
    for (uint64_t frame = 0; frame < 8; ++frame) {
      const bool normals = frame % 4 != 3;  // one frame of each kind without normals
      std::vector<MorphWeight> weights;
      if (frame % 2 == 0) weights = MakeMorphWeights(kTargets, frame == 4 ? 1 : kTargets, 3, frame);
      if (frame == 5) weights = zeros;
      ExpectMorphedFrame(backend, **prepared, method, normals, weights, frame,
                         /*unmorphed_differs=*/frame % 2 == 0,
                         "frame " + std::to_string(frame) + (normals ? " with normals" : ""));
    }
  }
}

// A face rig's scale: 300 targets, each moving 5% of the vertices, 250 of them active.
TEST_P(MorphFrameSequenceTest, HundredsOfActiveTargetsMatchTheReference) {
  Backend& backend = BackendById(GetParam());
  SKIP_IF_UNAVAILABLE(backend);
  constexpr uint32_t kTargets = 300;
  auto mesh =
      MorphMesh({.vertices = 4099, .influences = 3, .normals = true, .fraction = 0.05}, kTargets);
  ASSERT_NE(mesh, nullptr);
  auto prepared = backend.Prepare(mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  const auto weights = MakeMorphWeights(kTargets, 250, 9, 0);
  for (SkinningMethod method : backend.info().methods) {
    ExpectMorphedFrame(backend, **prepared, method, true, weights, 0, true, "250 active");
  }
}

INSTANTIATE_TEST_SUITE_P(AllBackends, MorphFrameSequenceTest,
                         ::testing::ValuesIn(ComputingBackendIds()), BackendName);

// The reference's morph on a case worked by hand: 0.5 * (0.2, 0, 0) - 2 * (0, 0.1, 0).
TEST(MorphReferenceTest, AddsWeightedDeltasInDouble) {
  MeshArrays arrays{.vertex_count = 2,
                    .influences = 1,
                    .joint_count = 1,
                    .positions = {1, 2, 3, 4, 5, 6},
                    .normals = {0, 0, 1, 0, 1, 0},
                    .tangents = {1, 0, 0, -1, 0, 0, 1, 1},
                    .joints = {0, 0},
                    .weights = {1, 1},
                    .morph_target_sizes = {1, 2},
                    .morph_indices = {1, 0, 1},
                    .morph_position_deltas = {0.2f, 0, 0, 0, 0, 1, 0, 0.1f, 0},
                    .morph_normal_deltas = {0, 0, 0, 1, 0, 0, 0, 0, 0},
                    .morph_tangent_deltas = {0, 0, 0, 0, 0.5f, 0, 0, 0, 0}};
  auto mesh = Mesh::Create(arrays);
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  const MorphWeight weights[] = {{0, 0.5f}, {1, -2.0f}};
  const ReferenceFrame rest = ReferenceMorph(**mesh, weights);
  EXPECT_NEAR(rest.positions[0], 1, 1e-12);
  EXPECT_NEAR(rest.positions[2], 3 - 2, 1e-12);
  EXPECT_NEAR(rest.positions[3], 4 + 0.5 * double{0.2f}, 1e-12);
  EXPECT_NEAR(rest.positions[4], 5 - 2 * double{0.1f}, 1e-12);
  EXPECT_NEAR(rest.normals[0], -2, 1e-12);
  EXPECT_NEAR(rest.tangents[1], -2 * 0.5,
              1e-12);               // vertex 0's tangent (1, 0, 0, -1) + -2 (0, 0.5, 0)
  EXPECT_EQ(rest.tangents[3], -1);  // w is never morphed
  // Skinned with the identity, the positions are the morphed rest.
  const std::vector<float> identity = MakeIdentityPalette(1);
  const ReferenceFrame skinned = ReferenceSkin(**mesh, identity, weights);
  EXPECT_NEAR(skinned.positions[4], 5 - 2 * double{0.1f}, 1e-12);
  const double length = std::sqrt(4.0 + 1.0);  // normal (-2, 0, 1) renormalised
  EXPECT_NEAR(skinned.normals[0], -2 / length, 1e-12);
  const double tangent_length = std::sqrt(1.0 + 1.0);  // tangent (1, -1, 0) renormalised
  EXPECT_NEAR(skinned.tangents[0], 1 / tangent_length, 1e-12);
  EXPECT_NEAR(skinned.tangents[1], -1 / tangent_length, 1e-12);
  EXPECT_EQ(skinned.tangents[3], -1);
}

}  // namespace
}  // namespace skinserve::testing
