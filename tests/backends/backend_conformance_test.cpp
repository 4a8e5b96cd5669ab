// Every computing backend against the independent float64 reference, on random valid
// meshes whose vertex counts are multiples of no SIMD width or work-group size, with
// 1..8 influences, 1..1024 joints, with and without normals. Tolerance: see
// CompareWithReference (1e-5 relative to the frame's scale for positions, 1e-5 for
// normals).
#include <gtest/gtest.h>

#include <tuple>

#include "backend_fixture.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::testing {
namespace {

struct Case {
  uint32_t vertices;
  uint32_t influences;
  uint32_t joints;
  bool normals;
};

std::vector<Case> Cases() {
  std::vector<Case> cases;
  for (uint32_t v : {1u, 7u, 1001u}) {
    for (uint32_t b = 1; b <= 8; ++b) {
      for (uint32_t j : {1u, 77u, 1024u}) {
        for (bool n : {false, true}) cases.push_back({v, b, j, n});
      }
    }
  }
  // Large, odd-sized meshes for the common influence counts.
  for (uint32_t b : {1u, 4u, 8u}) cases.push_back({100003, b, 77, b == 4});
  return cases;
}

class BackendConformanceTest : public ::testing::TestWithParam<std::tuple<std::string, Case>> {};

TEST_P(BackendConformanceTest, MatchesTheFloat64Reference) {
  const auto& [id, c] = GetParam();
  Backend& backend = BackendById(id);
  SKIP_IF_UNAVAILABLE(backend);
  const uint64_t seed = c.vertices * 131 + c.influences * 17 + c.joints + (c.normals ? 1 : 0);
  auto mesh = Mesh::Create(MakeSyntheticMesh({.vertex_count = c.vertices,
                                              .influences = c.influences,
                                              .joint_count = c.joints,
                                              .normals = c.normals,
                                              .seed = seed}));
  ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
  auto prepared = backend.Prepare(*mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  // Two different frames on the same prepared mesh: results must follow the palette.
  for (uint64_t frame = 0; frame < 2; ++frame) {
    const auto palette = MakeSyntheticPalette(c.joints, seed, frame * 7);
    const Output out = SkinOnce(backend, **prepared, palette, c.normals);
    const Deviation d = CompareWithReference(**mesh, palette, out.positions, out.normals);
    EXPECT_TRUE(d.within_tolerance())
        << id << " V=" << c.vertices << " B=" << c.influences << " J=" << c.joints
        << " normals=" << c.normals << " frame=" << frame << ": position error "
        << d.max_position_error << " (tolerance " << d.position_tolerance << "), normal error "
        << d.max_normal_error << " (tolerance " << d.normal_tolerance << "), worst vertex "
        << d.worst_vertex;
  }
}

std::string CaseName(const ::testing::TestParamInfo<std::tuple<std::string, Case>>& info) {
  const auto& [id, c] = info.param;
  std::string name = id + "_V" + std::to_string(c.vertices) + "_B" + std::to_string(c.influences) +
                     "_J" + std::to_string(c.joints) + (c.normals ? "_normals" : "");
  for (char& ch : name) {
    if (ch == '-') ch = '_';
  }
  return name;
}

INSTANTIATE_TEST_SUITE_P(AllBackends, BackendConformanceTest,
                         ::testing::Combine(::testing::ValuesIn(ComputingBackendIds()),
                                            ::testing::ValuesIn(Cases())),
                         CaseName);

}  // namespace
}  // namespace skinserve::testing
