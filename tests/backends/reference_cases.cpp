#include "reference_cases.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <string>

#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::testing {

std::vector<MeshCase> MeshCases(std::initializer_list<uint32_t> vertices,
                                std::initializer_list<uint32_t> joints, uint32_t max_influences) {
  // Under qemu (SKINSERVE_TEST_TARGET_MAX_VERTICES) a longer count becomes that count, once:
  // the suites' large cases still cover long frames there.
  std::vector<uint32_t> counts;
  for (uint32_t v : vertices) {
    const uint32_t count = std::min(v, TargetCheckMaxVertices());
    if (std::find(counts.begin(), counts.end(), count) == counts.end()) counts.push_back(count);
  }
  std::vector<MeshCase> cases;
  for (uint32_t v : counts) {
    for (uint32_t b = 1; b <= max_influences; ++b) {
      for (uint32_t j : joints) {
        cases.push_back({v, b, j, false});
        cases.push_back({v, b, j, true});
        cases.push_back({v, b, j, true, true});
      }
    }
  }
  return cases;
}

uint32_t LargeCaseVertices() {
  const char* text = std::getenv("SKINSERVE_TEST_LARGE_VERTICES");
  if (text == nullptr || *text == '\0') return 100003;
  // Called while the suites' cases are listed, before any test runs: a bad value ends the
  // run here, loudly.
  char* end = nullptr;
  const unsigned long value = std::strtoul(text, &end, 10);
  if (*end != '\0' || value < 4097 || value > 100003 || value % 2 == 0) {
    std::fprintf(stderr,
                 "SKINSERVE_TEST_LARGE_VERTICES=%s: expected an odd vertex count in "
                 "[4097, 100003]\n",
                 text);
    std::exit(2);
  }
  return static_cast<uint32_t>(value);
}

uint32_t TargetCheckMaxVertices() {
  const char* text = std::getenv("SKINSERVE_TEST_TARGET_MAX_VERTICES");
  if (text == nullptr) return std::numeric_limits<uint32_t>::max();
  char* end = nullptr;
  const unsigned long value = std::strtoul(text, &end, 10);
  if (end == text || *end != '\0' || value < 33) {
    // Read while the suites' cases are listed, before any test runs: the run ends here.
    std::fprintf(stderr,
                 "SKINSERVE_TEST_TARGET_MAX_VERTICES=%s: expected a vertex count of at least 33\n",
                 text);
    std::exit(2);
  }
  return static_cast<uint32_t>(
      std::min<unsigned long>(value, std::numeric_limits<uint32_t>::max()));
}

uint64_t CaseSeed(const MeshCase& c) {
  return c.vertices * 131ull + c.influences * 17ull + c.joints + (c.normals ? 1 : 0);
}

std::shared_ptr<const Mesh> CaseMesh(const MeshCase& c) {
  auto mesh = Mesh::Create(MakeSyntheticMesh({.vertex_count = c.vertices,
                                              .influences = c.influences,
                                              .joint_count = c.joints,
                                              .normals = c.normals,
                                              .tangents = c.tangents,
                                              .seed = CaseSeed(c)}));
  EXPECT_TRUE(mesh.ok()) << mesh.status().ToString();
  return mesh.ok() ? *mesh : nullptr;
}

std::string CaseName(const ::testing::TestParamInfo<BackendCase>& info) {
  const auto& [id, c] = info.param;
  std::string name = id + "_V" + std::to_string(c.vertices) + "_B" + std::to_string(c.influences) +
                     "_J" + std::to_string(c.joints) + (c.normals ? "_normals" : "") +
                     (c.tangents ? "_tangents" : "");
  std::replace(name.begin(), name.end(), '-', '_');
  return name;
}

void ExpectFrameMatchesReference(Backend& backend, const PreparedMesh& prepared, const Mesh& mesh,
                                 std::span<const float> palette, const MeshCase& c,
                                 SkinningMethod method, const std::string& what) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<float> positions(3ull * c.vertices, nan);
  std::vector<float> normals(c.normals ? 3ull * c.vertices : 0, nan);
  std::vector<float> tangents(c.tangents ? 4ull * c.vertices : 0, nan);
  SkinFrame frame;
  frame.palette = palette;
  frame.positions = positions;
  frame.normals = normals;
  frame.tangents = tangents;
  frame.method = method;
  const Status s = backend.Skin(prepared, frame);
  if (c.tangents && !backend.info().tangents) {
    EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition) << s.ToString();
    EXPECT_NE(s.message().find(backend.info().id), std::string::npos) << s.ToString();
    EXPECT_NE(s.message().find("simd"), std::string::npos) << s.ToString();
    return;
  }
  ASSERT_TRUE(s.ok()) << backend.info().id << " " << what << ": " << s.ToString();
  const Deviation d = CompareWithReference(mesh, palette, positions, normals, method, {}, tangents);
  EXPECT_TRUE(d.within_tolerance())
      << backend.info().id << " V=" << c.vertices << " B=" << c.influences << " J=" << c.joints
      << " normals=" << c.normals << " " << what << ": position error " << d.max_position_error
      << " (tolerance " << d.position_tolerance << "), normal error " << d.max_normal_error
      << " (tolerance " << d.normal_tolerance << "), tangent error " << d.max_tangent_error
      << " (tolerance " << d.tangent_tolerance << "), worst vertex " << d.worst_vertex;
}

}  // namespace skinserve::testing
