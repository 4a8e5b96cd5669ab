// `simd` and `simd-openmp` at every SIMD target this binary and CPU can run (AVX3, AVX2,
// SSE4 and the scalar fallback on an AVX-512 machine; NEON and SVE under qemu-aarch64),
// each capped at it the way SKINSERVE_SIMD_MAX_TARGET caps it, against the float64
// reference, in both skinning methods (linear blending on scaled palettes, dual
// quaternions on rigid ones): every influence count 1..8, without normals, with normals,
// with normals and tangents, 8-bit and 16-bit joint streams (and the dual-quaternion sign
// table, built or not), and every tail length (1..33 vertices, and around the 256-vertex
// chunks the normals are renormalised in). Writing outside the frame is caught by guard
// floats on both sides of each output.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <limits>

#include "backend_fixture.h"
#include "reference_cases.h"
#include "skinserve/engine/simd_targets.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::testing {
namespace {

constexpr float kGuard = 12345.0f;
constexpr std::size_t kGuardFloats = 4;

// Every tail length, and around the 256-vertex chunks, up to TargetCheckMaxVertices().
std::vector<uint32_t> VertexCounts() {
  const uint32_t limit = TargetCheckMaxVertices();
  std::vector<uint32_t> counts;
  for (uint32_t v = 1; v <= 33; ++v) counts.push_back(v);
  for (uint32_t v : {255u, 256u, 257u, 511u, 513u, 1001u}) {
    if (v <= limit) counts.push_back(v);
  }
  return counts;
}

// Skins into outputs with guard floats before and after; checks both the reference and
// the guards. `palette_scale` multiplies every palette entry (linear blending only).
void ExpectMatchesReference(Backend& backend, uint32_t vertices, uint32_t influences,
                            uint32_t joints, bool normals, bool tangents, SkinningMethod method,
                            float palette_scale = 1.0f) {
  const uint64_t seed = vertices * 131 + influences * 17 + joints + (normals ? 1 : 0);
  auto mesh = Mesh::Create(MakeSyntheticMesh({.vertex_count = vertices,
                                              .influences = influences,
                                              .joint_count = joints,
                                              .normals = normals,
                                              .tangents = tangents,
                                              .seed = seed}));
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  auto prepared = backend.Prepare(*mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  const std::size_t n = 3ull * vertices;
  auto palette = method == SkinningMethod::kDualQuaternion ? MakeRigidPalette(joints, seed, 3)
                                                           : MakeSyntheticPalette(joints, seed, 3);
  for (float& entry : palette) entry *= palette_scale;
  std::vector<float> positions(n + 2 * kGuardFloats, kGuard);
  std::vector<float> normal_out(normals ? n + 2 * kGuardFloats : 0, kGuard);
  const std::span<float> p(positions.data() + kGuardFloats, n);
  const std::span<float> nn =
      normals ? std::span<float>(normal_out.data() + kGuardFloats, n) : std::span<float>();
  std::fill(p.begin(), p.end(), std::numeric_limits<float>::quiet_NaN());
  std::fill(nn.begin(), nn.end(), std::numeric_limits<float>::quiet_NaN());
  std::vector<float> tangent_out(tangents ? 4ull * vertices + 2 * kGuardFloats : 0, kGuard);
  const std::span<float> t =
      tangents ? std::span<float>(tangent_out.data() + kGuardFloats, 4ull * vertices)
               : std::span<float>();
  std::fill(t.begin(), t.end(), std::numeric_limits<float>::quiet_NaN());
  const SkinFrame frame{
      .palette = palette, .positions = p, .normals = nn, .tangents = t, .method = method};
  ASSERT_TRUE(frame.Validate(**mesh).ok());
  const Status skinned = backend.Skin(**prepared, frame);
  ASSERT_TRUE(skinned.ok()) << skinned.ToString();
  const std::string what = backend.info().id + " at " + backend.info().simd_target + " " +
                           std::string(MethodName(method)) + " V=" + std::to_string(vertices) +
                           " B=" + std::to_string(influences) + " J=" + std::to_string(joints) +
                           (normals ? " normals" : "") + (tangents ? " tangents" : "");
  const Deviation d = CompareWithReference(**mesh, palette, p, nn, method, {}, t);
  EXPECT_TRUE(d.within_tolerance())
      << what << ": position error " << d.max_position_error << " (tolerance "
      << d.position_tolerance << "), normal error " << d.max_normal_error << " (tolerance "
      << d.normal_tolerance << "), tangent error " << d.max_tangent_error << " (tolerance "
      << d.tangent_tolerance << "), worst vertex " << d.worst_vertex;
  for (const std::vector<float>* out : {&positions, &normal_out, &tangent_out}) {
    if (out->empty()) continue;
    for (std::size_t i = 0; i < kGuardFloats; ++i) {
      EXPECT_EQ((*out)[i], kGuard) << what << ": wrote before the output";
      EXPECT_EQ((*out)[out->size() - 1 - i], kGuard) << what << ": wrote past the output";
    }
  }
}

class SimdTargetTest : public ::testing::TestWithParam<std::string> {};

void ExpectBothBackendsMatchAt(const std::string& target, SkinningMethod method) {
  for (int threads : {0, 2}) {  // simd, simd-openmp
    const auto backend = CreateSimdBackend(threads, target);
    ASSERT_TRUE(backend->info().available) << backend->info().unavailable_reason;
    ASSERT_EQ(backend->info().simd_target, target) << "the cap did not select the target";
    ASSERT_TRUE(backend->info().Supports(method));
    for (uint32_t b = 1; b <= 8; ++b) {
      // 8-bit joints up to 256, 16-bit above; with 20 joints the dual-quaternion kernel
      // takes its per-frame hemisphere table from 400 / (B - 1) vertices on, per-vertex signs
      // below.
      for (uint32_t j : {1u, 20u, 256u, 300u}) {
        for (int outputs = 0; outputs < 3; ++outputs) {  // positions, + normals, + tangents
          for (uint32_t v : VertexCounts()) {
            ExpectMatchesReference(*backend, v, b, j, outputs >= 1, outputs == 2, method);
            if (::testing::Test::HasFatalFailure()) return;
          }
        }
      }
    }
  }
}

TEST_P(SimdTargetTest, BothBackendsMatchTheFloat64ReferenceAtThisTarget) {
  ExpectBothBackendsMatchAt(GetParam(), SkinningMethod::kLinear);
}

TEST_P(SimdTargetTest, BothBackendsMatchTheDualQuaternionReferenceAtThisTarget) {
  ExpectBothBackendsMatchAt(GetParam(), SkinningMethod::kDualQuaternion);
}

// Normals are renormalised from an estimate of 1 / length refined by a Newton step, which
// is wrong for lengths whose square is denormal (the estimate gives infinity); such vectors
// take the exact 1 / sqrt. Palettes scaled by 1e-17, 1e-19 and 3e-20 make the skinned
// normals' squared lengths about 1e-34 (the estimate), 1e-38 (both) and 1e-39 (denormal):
// the normals must still match the reference's directions. (Below that float's denormal
// squares lose the bits the exact path needs too.)
TEST_P(SimdTargetTest, NormalsShrunkToDenormalLengthsStillComeOutUnit) {
  for (int threads : {0, 2}) {
    const auto backend = CreateSimdBackend(threads, GetParam());
    ASSERT_TRUE(backend->info().available) << backend->info().unavailable_reason;
    for (float scale : {1e-17f, 1e-19f, 3e-20f}) {
      for (uint32_t v : {37u, 1001u}) {
        ExpectMatchesReference(*backend, v, 2, 20, true, false, SkinningMethod::kLinear, scale);
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(RunnableHere, SimdTargetTest, ::testing::ValuesIn(RunnableSimdTargets()),
                         [](const ::testing::TestParamInfo<std::string>& param_info) {
                           return param_info.param;
                         });

TEST(SimdTargetsTest, ListsTheBestTargetFirstAndTheRegistryUsesIt) {
  const std::vector<std::string> targets = RunnableSimdTargets();
  ASSERT_FALSE(targets.empty());
  // Where ctest knows the CPU (qemu's, on arm64), it says which targets must be there.
  if (const char* expected_targets = std::getenv("SKINSERVE_EXPECT_SIMD_TARGETS")) {
    std::string joined;
    for (const std::string& t : targets) joined += (joined.empty() ? "" : ",") + t;
    EXPECT_EQ(joined, expected_targets);
  }
  // The registry's `simd` honours SKINSERVE_SIMD_MAX_TARGET (a ctest runs this binary
  // with it set); unset, it takes the best.
  const char* cap = std::getenv(kSimdMaxTargetVariable);
  const std::string expected = cap != nullptr ? cap : targets.front();
  for (const char* id : {"simd", "simd-openmp"}) {
    const BackendInfo& info = BackendById(id).info();
    EXPECT_TRUE(info.available) << id << ": " << info.unavailable_reason;
    EXPECT_EQ(info.simd_target, expected) << id;
    EXPECT_GE(info.simd_width, 1) << id;
  }
  EXPECT_EQ(BackendById("simd").info().threads, 1);
  EXPECT_EQ(BackendById("simd-openmp").info().threads, 2);
}

TEST(SimdTargetsTest, AnUnknownCapGivesAnUnavailableBackendThatSaysWhy) {
  const auto backend = CreateSimdBackend(1, "AVX9000");
  EXPECT_FALSE(backend->info().available);
  EXPECT_NE(backend->info().unavailable_reason.find("AVX9000"), std::string::npos)
      << backend->info().unavailable_reason;
  EXPECT_NE(backend->info().unavailable_reason.find(RunnableSimdTargets().front()),
            std::string::npos)
      << "the reason lists the runnable targets: " << backend->info().unavailable_reason;
  auto mesh = Mesh::Create(MakeSyntheticMesh({.vertex_count = 4})).value();
  EXPECT_EQ(backend->Prepare(mesh).status().code(), StatusCode::kFailedPrecondition);
}

}  // namespace
}  // namespace skinserve::testing
