// Both OpenCL backends against the float64 reference where the OpenCL code has its own
// cases: every kernel (B = 1..8, with and without normals), vertex counts around a
// work-item's 4 vertices and a work-group's 256 (the last item clamps, items past the end
// return), palettes of 1 to 1024 joints (48 KB), and outputs and palettes that are not
// 64-byte aligned (the zero-copy backend wraps them in place).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <tuple>

#include "opencl_test_support.h"
#include "skinserve/model/aligned_buffer.h"
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
  for (uint32_t v : {1u, 2u, 3u, 4u, 5u, 7u, 255u, 256u, 257u, 1001u}) {
    for (uint32_t b = 1; b <= kMaxInfluences; ++b) {
      for (uint32_t j : {1u, 77u, 1024u}) {
        for (bool n : {false, true}) cases.push_back({v, b, j, n});
      }
    }
  }
  for (uint32_t b = 1; b <= kMaxInfluences; ++b) {
    for (bool n : {false, true}) cases.push_back({100003, b, 77, n});
  }
  cases.push_back({100003, 8, 1024, true});
  return cases;
}

class OpenClReferenceTest : public ::testing::TestWithParam<std::tuple<std::string, Case>> {};

TEST_P(OpenClReferenceTest, MatchesTheFloat64Reference) {
  const auto& [id, c] = GetParam();
  Backend& backend = OpenClBackend(id);
  SKIP_IF_OPENCL_UNAVAILABLE(backend);
  const uint64_t seed = 7919ull * c.vertices + 31 * c.influences + c.joints + c.normals;
  auto mesh = SyntheticMesh(c.vertices, c.influences, c.joints, c.normals, seed);
  auto prepared = backend.Prepare(mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  // Outputs pre-filled with NaN: an element the kernel skips shows up as an error.
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<float> positions(3ull * c.vertices, nan);
  std::vector<float> normals(c.normals ? 3ull * c.vertices : 0, nan);
  const auto palette = MakeSyntheticPalette(c.joints, seed, 3);
  ASSERT_TRUE(backend.Skin(**prepared, {palette, positions, normals}).ok());
  EXPECT_EQ(ReferenceMismatch(*mesh, palette, positions, normals), "")
      << id << " V=" << c.vertices << " B=" << c.influences << " J=" << c.joints
      << " normals=" << c.normals;
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

INSTANTIATE_TEST_SUITE_P(OpenCl, OpenClReferenceTest,
                         ::testing::Combine(::testing::ValuesIn(OpenClBackendIds()),
                                            ::testing::ValuesIn(Cases())),
                         CaseName);

class OpenClAlignmentTest : public ::testing::TestWithParam<std::string> {};

// Outputs and palette start one float past a 64-byte boundary; guard floats on both sides
// of each output must stay untouched (no kernel writes past the span's ends).
TEST_P(OpenClAlignmentTest, MisalignedOutputsAndPaletteAreSkinnedInPlaceCorrectly) {
  Backend& backend = OpenClBackend(GetParam());
  SKIP_IF_OPENCL_UNAVAILABLE(backend);
  constexpr float kGuard = -12345.0f;
  constexpr std::size_t kOffset = 1;  // floats: 4-byte aligned, never 64-byte aligned
  for (uint32_t v : {5u, 1001u, 100003u}) {
    for (bool with_normals : {false, true}) {
      auto mesh = SyntheticMesh(v, 4, 77, true, v);
      auto prepared = backend.Prepare(mesh);
      ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
      const std::size_t n = 3ull * v;
      AlignedBuffer<float> positions_storage(n + 2 * kOffset), normals_storage(n + 2 * kOffset);
      for (auto* storage : {&positions_storage, &normals_storage}) {
        for (std::size_t i = 0; i < storage->size(); ++i) (*storage)[i] = kGuard;
      }
      const auto palette_values = MakeSyntheticPalette(77, v, 5);
      AlignedBuffer<float> palette_storage(palette_values.size() + kOffset);
      std::copy(palette_values.begin(), palette_values.end(), palette_storage.data() + kOffset);
      const std::span<const float> palette(palette_storage.data() + kOffset, palette_values.size());
      const std::span<float> positions(positions_storage.data() + kOffset, n);
      const std::span<float> normals =
          with_normals ? std::span<float>(normals_storage.data() + kOffset, n) : std::span<float>();
      ASSERT_NE(reinterpret_cast<uintptr_t>(positions.data()) % kBufferAlignment, 0u);
      ASSERT_TRUE(backend.Skin(**prepared, {palette, positions, normals}).ok());
      EXPECT_EQ(ReferenceMismatch(*mesh, palette, positions, normals), "")
          << "V=" << v << " normals=" << with_normals;
      for (const auto* storage : {&positions_storage, &normals_storage}) {
        EXPECT_EQ((*storage)[0], kGuard) << "V=" << v << ": written before the output";
        EXPECT_EQ((*storage)[n + kOffset], kGuard) << "V=" << v << ": written past the output";
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(OpenCl, OpenClAlignmentTest, ::testing::ValuesIn(OpenClBackendIds()),
                         BackendTestName);

}  // namespace
}  // namespace skinserve::testing
