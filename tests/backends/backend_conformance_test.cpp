// Every computing backend against the independent float64 reference, on random valid
// meshes whose vertex counts are multiples of no SIMD width or work-group size, with
// 1..8 influences, 1..1024 joints, without normals, with normals, with normals and tangents.
// Tolerance: see CompareWithReference (1e-5 relative to the frame's scale for positions, 1e-5 for
// normals).
#include <gtest/gtest.h>

#include <tuple>

#include "backend_fixture.h"
#include "reference_cases.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::testing {
namespace {

std::vector<MeshCase> Cases() {
  std::vector<MeshCase> cases = MeshCases({1, 7, 1001}, {1, 77, 1024});
  // Large, odd-sized meshes for the common influence counts.
  for (uint32_t b : {1u, 4u, 8u}) cases.push_back({LargeCaseVertices(), b, 77, b == 4, b == 4});
  return cases;
}

class BackendConformanceTest : public ::testing::TestWithParam<BackendCase> {};

TEST_P(BackendConformanceTest, MatchesTheFloat64Reference) {
  const auto& [id, c] = GetParam();
  Backend& backend = BackendById(id);
  SKIP_IF_UNAVAILABLE(backend);
  auto mesh = CaseMesh(c);
  ASSERT_NE(mesh, nullptr);
  auto prepared = backend.Prepare(mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  // Two different frames on the same prepared mesh: results must follow the palette.
  for (uint64_t frame = 0; frame < 2; ++frame) {
    const auto palette = MakeSyntheticPalette(c.joints, CaseSeed(c), frame * 7);
    ExpectFrameMatchesReference(backend, **prepared, *mesh, palette, c, SkinningMethod::kLinear,
                                "frame " + std::to_string(frame));
  }
}

INSTANTIATE_TEST_SUITE_P(AllBackends, BackendConformanceTest,
                         ::testing::Combine(::testing::ValuesIn(ComputingBackendIds()),
                                            ::testing::ValuesIn(Cases())),
                         CaseName);

}  // namespace
}  // namespace skinserve::testing
