// Both OpenCL backends against the float64 reference where the OpenCL code has its own
// cases: every kernel (B = 1..8, with and without normals, linear blending and dual
// quaternions, each against its own reference), vertex counts around a
// work-item's 4 vertices and a work-group's 256 (the last item clamps, items past the end
// return), palettes of 1 to 1024 joints (48 KB), and outputs and palettes that are not
// 64-byte aligned (the zero-copy backend wraps them in place). Every case also with normals
// and tangents (the *_tangents_* kernels; xyz within the normals' 1e-5, w exact:
// CompareWithReference), the long frames at B = 4.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <tuple>
#include <utility>

#include "opencl_test_support.h"
#include "reference_cases.h"
#include "skinserve/model/aligned_buffer.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::testing {
namespace {

std::vector<MeshCase> Cases() {
  std::vector<MeshCase> cases = MeshCases({1, 2, 3, 4, 5, 7, 255, 256, 257, 1001}, {1, 77, 1024});
  // The long frames (8 chunks on the staged runtimes): tangents at B = 4 only, where the
  // short cases above run every tangent kernel (each large tangent case costs ~2 s of
  // float64 reference and PoCL on the 2-core CI machine).
  for (const MeshCase& c : MeshCases({100003}, {77})) {
    if (!c.tangents || c.influences == 4) cases.push_back(c);
  }
  cases.push_back({100003, 8, 1024, true});
  return cases;
}

class OpenClReferenceTest : public ::testing::TestWithParam<BackendCase> {};

TEST_P(OpenClReferenceTest, MatchesTheFloat64Reference) {
  const auto& [id, c] = GetParam();
  Backend& backend = OpenClBackend(id);
  SKIP_IF_OPENCL_UNAVAILABLE(backend);
  auto mesh = CaseMesh(c);
  ASSERT_NE(mesh, nullptr);
  auto prepared = backend.Prepare(mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  const auto palette = MakeSyntheticPalette(c.joints, CaseSeed(c), 3);
  ExpectFrameMatchesReference(backend, **prepared, *mesh, palette, c, SkinningMethod::kLinear,
                              "frame 3");
  // The same prepared mesh in dual quaternions (dqs_* kernels), on a rigid palette.
  const auto rigid = MakeRigidPalette(c.joints, CaseSeed(c), 3);
  ExpectFrameMatchesReference(backend, **prepared, *mesh, rigid, c, SkinningMethod::kDualQuaternion,
                              "rigid frame 3");
}

INSTANTIATE_TEST_SUITE_P(OpenCl, OpenClReferenceTest,
                         ::testing::Combine(::testing::ValuesIn(OpenClBackendIds()),
                                            ::testing::ValuesIn(Cases())),
                         CaseName);

class OpenClAlignmentTest : public ::testing::TestWithParam<std::string> {};

// Outputs and palette start one float past a 64-byte boundary; guard floats on both sides
// of each output must stay untouched (no kernel writes past the span's ends). Positions
// alone, with normals, and with normals and tangents (4 floats a vertex).
TEST_P(OpenClAlignmentTest, MisalignedOutputsAndPaletteAreSkinnedInPlaceCorrectly) {
  Backend& backend = OpenClBackend(GetParam());
  SKIP_IF_OPENCL_UNAVAILABLE(backend);
  constexpr float kGuard = -12345.0f;
  constexpr std::size_t kOffset = 1;  // floats: 4-byte aligned, never 64-byte aligned
  for (uint32_t v : {5u, 1001u, 100003u}) {
    auto mesh = SyntheticMesh(v, 4, 77, true, v, /*tangents=*/true);
    auto prepared = backend.Prepare(mesh);
    ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
    for (int outputs = 0; outputs < 3; ++outputs) {  // positions, + normals, + tangents
      const bool with_normals = outputs >= 1, with_tangents = outputs == 2;
      const std::size_t n = 3ull * v, t = 4ull * v;
      AlignedBuffer<float> positions_storage(n + 2 * kOffset), normals_storage(n + 2 * kOffset),
          tangents_storage(t + 2 * kOffset);
      for (auto* storage : {&positions_storage, &normals_storage, &tangents_storage}) {
        for (std::size_t i = 0; i < storage->size(); ++i) (*storage)[i] = kGuard;
      }
      const auto palette_values = MakeSyntheticPalette(77, v, 5);
      AlignedBuffer<float> palette_storage(palette_values.size() + kOffset);
      std::copy(palette_values.begin(), palette_values.end(), palette_storage.data() + kOffset);
      const std::span<const float> palette(palette_storage.data() + kOffset, palette_values.size());
      const std::span<float> positions(positions_storage.data() + kOffset, n);
      const std::span<float> normals =
          with_normals ? std::span<float>(normals_storage.data() + kOffset, n) : std::span<float>();
      const std::span<float> tangents = with_tangents
                                            ? std::span<float>(tangents_storage.data() + kOffset, t)
                                            : std::span<float>();
      ASSERT_NE(reinterpret_cast<uintptr_t>(positions.data()) % kBufferAlignment, 0u);
      const SkinFrame frame{
          .palette = palette, .positions = positions, .normals = normals, .tangents = tangents};
      ASSERT_TRUE(backend.Skin(**prepared, frame).ok());
      EXPECT_EQ(ReferenceMismatch(*mesh, palette, positions, normals, tangents), "")
          << "V=" << v << " outputs=" << outputs;
      const std::pair<const AlignedBuffer<float>*, std::size_t> guarded[] = {
          {&positions_storage, n}, {&normals_storage, n}, {&tangents_storage, t}};
      for (const auto& [storage, size] : guarded) {
        EXPECT_EQ((*storage)[0], kGuard) << "V=" << v << ": written before the output";
        EXPECT_EQ((*storage)[size + kOffset], kGuard) << "V=" << v << ": written past the output";
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(OpenCl, OpenClAlignmentTest, ::testing::ValuesIn(OpenClBackendIds()),
                         BackendTestName);

}  // namespace
}  // namespace skinserve::testing
