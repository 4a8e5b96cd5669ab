// Properties every backend must have, checked against values the test computes itself:
// the identity palette returns the rest pose, one rigid transform for all joints moves
// every vertex rigidly, every output element is written, results do not depend on the
// output's alignment, on a partial last block or on other threads skinning the same mesh.
#include <gtest/gtest.h>

#include <cmath>
#include <thread>

#include "backend_fixture.h"
#include "skinserve/reference/reference.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::testing {
namespace {

class BackendPropertiesTest : public ::testing::TestWithParam<std::string> {
 protected:
  Backend& backend() { return BackendById(GetParam()); }
  static std::shared_ptr<const Mesh> MakeMesh(uint32_t vertices, uint32_t influences) {
    return Mesh::Create(MakeSyntheticMesh({.vertex_count = vertices,
                                           .influences = influences,
                                           .normals = true,
                                           .seed = vertices + influences}))
        .value();
  }
};

TEST_P(BackendPropertiesTest, IdentityPaletteReturnsTheRestPose) {
  SKIP_IF_UNAVAILABLE(backend());
  for (uint32_t b : {1u, 3u, 8u}) {
    auto mesh = MakeMesh(517, b);
    auto prepared = backend().Prepare(mesh).value();
    const Output out = SkinOnce(backend(), *prepared, MakeIdentityPalette(77), true);
    for (std::size_t i = 0; i < out.positions.size(); ++i) {
      ASSERT_NEAR(out.positions[i], mesh->positions()[i], 1e-5) << "B=" << b << " element " << i;
      ASSERT_NEAR(out.normals[i], mesh->normals()[i], 1e-5) << "B=" << b << " element " << i;
    }
  }
}

TEST_P(BackendPropertiesTest, OneRigidTransformForAllJointsMovesEveryVertexRigidly) {
  SKIP_IF_UNAVAILABLE(backend());
  // A rotation of 0.7 rad about the unit axis (2, 3, 6) / 7, then a translation.
  const double angle = 0.7, c = std::cos(angle), s = std::sin(angle);
  const double x = 2.0 / 7, y = 3.0 / 7, z = 6.0 / 7;
  const double r[3][3] = {{c + x * x * (1 - c), x * y * (1 - c) - z * s, x * z * (1 - c) + y * s},
                          {y * x * (1 - c) + z * s, c + y * y * (1 - c), y * z * (1 - c) - x * s},
                          {z * x * (1 - c) - y * s, z * y * (1 - c) + x * s, c + z * z * (1 - c)}};
  const double t[3] = {0.5, -1.25, 2.0};
  std::vector<float> palette(12 * 77);
  for (int j = 0; j < 77; ++j) {
    for (int row = 0; row < 3; ++row) {
      for (int col = 0; col < 3; ++col) palette[12 * j + 4 * row + col] = float(r[row][col]);
      palette[12 * j + 4 * row + 3] = float(t[row]);
    }
  }
  auto mesh = MakeMesh(1003, 4);
  auto prepared = backend().Prepare(mesh).value();
  const Output out = SkinOnce(backend(), *prepared, palette, true);
  for (uint32_t v = 0; v < mesh->vertex_count(); ++v) {
    const float* p = &mesh->positions()[3 * v];
    const float* n = &mesh->normals()[3 * v];
    for (int row = 0; row < 3; ++row) {
      const double expected_p = r[row][0] * p[0] + r[row][1] * p[1] + r[row][2] * p[2] + t[row];
      const double expected_n = r[row][0] * n[0] + r[row][1] * n[1] + r[row][2] * n[2];
      ASSERT_NEAR(out.positions[3 * v + row], expected_p, 1e-5) << "vertex " << v;
      ASSERT_NEAR(out.normals[3 * v + row], expected_n, 1e-5) << "vertex " << v;
    }
  }
}

TEST_P(BackendPropertiesTest, WritesEveryOutputElementAtAnyAlignment) {
  SKIP_IF_UNAVAILABLE(backend());
  auto mesh = MakeMesh(1001, 2);
  auto prepared = backend().Prepare(mesh).value();
  const auto palette = MakeSyntheticPalette(77, 5, 3);
  // Outputs start one float past an aligned address, with sentinels around them.
  const std::size_t n = 3ull * mesh->vertex_count();
  std::vector<float> positions(n + 2, -7.0f), normals(n + 2, -7.0f);
  std::fill(positions.begin() + 1, positions.end() - 1, std::nanf(""));
  std::fill(normals.begin() + 1, normals.end() - 1, std::nanf(""));
  const SkinFrame frame{palette, std::span<float>(positions).subspan(1, n),
                        std::span<float>(normals).subspan(1, n)};
  ASSERT_TRUE(backend().Skin(*prepared, frame).ok());
  const Deviation d = CompareWithReference(*mesh, palette, frame.positions, frame.normals);
  EXPECT_TRUE(d.within_tolerance()) << d.max_position_error << " " << d.max_normal_error;
  EXPECT_EQ(positions.front(), -7.0f);
  EXPECT_EQ(positions.back(), -7.0f);
  EXPECT_EQ(normals.front(), -7.0f);
  EXPECT_EQ(normals.back(), -7.0f);
}

TEST_P(BackendPropertiesTest, EveryVertexCountUpToTwoBlocksOfEight) {
  // SIMD and work-group backends handle a partial block at the end: every length of it.
  SKIP_IF_UNAVAILABLE(backend());
  for (uint32_t v = 1; v <= 17; ++v) {
    for (uint32_t b = 1; b <= kMaxInfluences; ++b) {
      auto mesh = MakeMesh(v, b);
      auto prepared = backend().Prepare(mesh).value();
      const auto palette = MakeSyntheticPalette(77, v, b);
      const Output out = SkinOnce(backend(), *prepared, palette, true);
      const Deviation d = CompareWithReference(*mesh, palette, out.positions, out.normals);
      ASSERT_TRUE(d.within_tolerance())
          << "V=" << v << " B=" << b << ": position error " << d.max_position_error
          << ", normal error " << d.max_normal_error << ", worst vertex " << d.worst_vertex;
    }
  }
}

TEST_P(BackendPropertiesTest, ConcurrentFramesOnOneMeshStayCorrect) {
  SKIP_IF_UNAVAILABLE(backend());
  auto mesh = MakeMesh(20011, 3);
  auto prepared = backend().Prepare(mesh).value();
  std::vector<std::thread> threads;
  std::vector<Deviation> deviations(4);
  for (int i = 0; i < 4; ++i) {
    threads.emplace_back([&, i] {
      for (int frame = 0; frame < 3; ++frame) {
        const auto palette = MakeSyntheticPalette(77, 100 + i, frame);
        const Output out = SkinOnce(backend(), *prepared, palette, frame % 2 == 0);
        const Deviation d = CompareWithReference(*mesh, palette, out.positions, out.normals);
        if (!d.within_tolerance()) deviations[i] = d;
      }
    });
  }
  for (auto& thread : threads) thread.join();
  for (const Deviation& d : deviations) {
    EXPECT_EQ(d.max_position_error, 0.0) << "a concurrent frame was wrong";
    EXPECT_EQ(d.max_normal_error, 0.0);
  }
}

std::string IdName(const ::testing::TestParamInfo<std::string>& param) {
  std::string name = param.param;
  for (char& ch : name) {
    if (ch == '-') ch = '_';
  }
  return name;
}

INSTANTIATE_TEST_SUITE_P(AllBackends, BackendPropertiesTest,
                         ::testing::ValuesIn(ComputingBackendIds()), IdName);

TEST(PassthroughBackendTest, ReturnsTheRestPoseWhateverThePalette) {
  Backend& backend = BackendById("passthrough");
  auto mesh = Mesh::Create(MakeSyntheticMesh({.vertex_count = 99, .normals = true})).value();
  auto prepared = backend.Prepare(mesh).value();
  const Output out = SkinOnce(backend, *prepared, MakeSyntheticPalette(77, 1, 1), true);
  EXPECT_TRUE(std::equal(out.positions.begin(), out.positions.end(), mesh->positions().begin()));
  EXPECT_TRUE(std::equal(out.normals.begin(), out.normals.end(), mesh->normals().begin()));
}

// A frame's tangents: only from a mesh that has them, with normals, 4 floats a vertex.
TEST(SkinFrameTest, TangentsNeedTheMeshsTangentsNormalsAndFourFloatsAVertex) {
  auto with = Mesh::Create(MakeSyntheticMesh(
                               {.vertex_count = 5, .normals = true, .tangents = true, .seed = 3}))
                  .value();
  auto without =
      Mesh::Create(MakeSyntheticMesh({.vertex_count = 5, .normals = true, .seed = 3})).value();
  const auto palette = MakeSyntheticPalette(77, 1, 1);
  std::vector<float> positions(15), normals(15), tangents(20), short_tangents(19);
  SkinFrame frame{
      .palette = palette, .positions = positions, .normals = normals, .tangents = tangents};
  EXPECT_TRUE(frame.Validate(*with).ok());
  Status s = frame.Validate(*without);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(s.message(), "tangents were requested but the mesh has none");
  frame.normals = {};
  s = frame.Validate(*with);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("tangents were requested without normals"), std::string::npos);
  frame.normals = normals;
  frame.tangents = short_tangents;
  s = frame.Validate(*with);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(s.message(), "tangents output holds 19 floats; expected 4 * vertex_count = 20");
}

// Every backend that runs here skins tangents: the CPU ones, the OpenCL ones (their
// *_tangents_* kernels) and passthrough (the rest tangents). Backends this build cannot run
// (sse on arm64, OpenCL without a platform) skin nothing. A backend that does not skin
// them (BackendInfo::tangents false, as a new backend starts) is refused naming the
// backends that do.
TEST(BackendListTest, EveryBackendSkinsTangentsOneThatDoesNotIsRefused) {
  int skinning = 0;
  for (const auto& backend : AllBackends()) {
    const std::string& id = backend->info().id;
    if (!backend->info().available) continue;
    EXPECT_TRUE(backend->info().tangents) << id;
    EXPECT_TRUE(CheckTangentSupport(backend->info(), true).ok()) << id;
    EXPECT_TRUE(CheckTangentSupport(backend->info(), false).ok()) << id;
    ++skinning;
  }
  EXPECT_GE(skinning, 4);  // serial, openmp, simd, simd-openmp run everywhere
  BackendInfo without;
  without.id = "no-tangents";
  ASSERT_FALSE(without.tangents);  // the default: a backend must say it skins them
  const Status s = CheckTangentSupport(without, true);
  EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(s.message().find("backend 'no-tangents' does not skin tangents"), std::string::npos)
      << s.message();
  EXPECT_NE(s.message().find("opencl, opencl-zerocopy)"), std::string::npos) << s.message();
  EXPECT_TRUE(CheckTangentSupport(without, false).ok());
}

TEST(PassthroughBackendTest, ReturnsTheRestTangents) {
  Backend& backend = BackendById("passthrough");
  auto mesh =
      Mesh::Create(MakeSyntheticMesh({.vertex_count = 9, .normals = true, .tangents = true}))
          .value();
  auto prepared = backend.Prepare(mesh).value();
  std::vector<float> positions(27), normals(27), tangents(36, std::nanf(""));
  const auto palette = MakeSyntheticPalette(77, 1, 1);
  const SkinFrame frame{
      .palette = palette, .positions = positions, .normals = normals, .tangents = tangents};
  ASSERT_TRUE(backend.Skin(*prepared, frame).ok());
  EXPECT_TRUE(std::equal(tangents.begin(), tangents.end(), mesh->tangents().begin()));
}

TEST(BackendListTest, HasEveryPaperBackendInTheDesignOrder) {
  std::vector<std::string> ids;
  for (const auto& backend : AllBackends()) ids.push_back(backend->info().id);
  const std::vector<std::string> expected = {
      "serial", "openmp",          "sse",        "sse-openmp", "simd", "simd-openmp",
      "opencl", "opencl-zerocopy", "passthrough"};
  EXPECT_EQ(ids, expected);
}

TEST(BackendListTest, CpuBackendsAreAvailableAndDescribeThemselves) {
  // SSE2 is part of x86-64, so nothing but OpenCL may be missing on an x86 machine; on
  // others the SSE backends are listed, unavailable, saying why.
  for (const auto& backend : AllBackends()) {
    const BackendInfo& info = backend->info();
    if (info.id.rfind("opencl", 0) == 0) continue;
    if (!kSseBackendsRunHere && IsSseBackend(info.id)) {
      EXPECT_FALSE(info.available) << info.id;
      EXPECT_NE(info.unavailable_reason.find("x86"), std::string::npos) << info.unavailable_reason;
    } else {
      EXPECT_TRUE(info.available) << info.id << ": " << info.unavailable_reason;
    }
    EXPECT_FALSE(info.description.empty()) << info.id;
    EXPECT_FALSE(info.device.empty()) << info.id;
    EXPECT_GE(info.threads, 1) << info.id;
  }
  EXPECT_EQ(BackendById("serial").info().simd_width, 1);
  EXPECT_EQ(BackendById("openmp").info().threads, 2);
  if (kSseBackendsRunHere) {
    EXPECT_EQ(BackendById("sse").info().simd_width, 4);
  }
  EXPECT_EQ(BackendById("sse-openmp").info().threads, 2);
}

// The engine's scheduler narrows a parallel backend's frame to one thread while other
// frames wait (SkinFrame::threads >= min_threads): each must say it can and still be right.
TEST(BackendListTest, ParallelCpuBackendsRunOnAsFewThreadsAsTheSchedulerGives) {
  auto mesh = Mesh::Create(MakeSyntheticMesh({.vertex_count = 1001, .influences = 3})).value();
  const auto palette = MakeSyntheticPalette(77, 4, 1);
  for (const char* id : {"openmp", "sse-openmp", "simd-openmp"}) {
    if (!kSseBackendsRunHere && IsSseBackend(id)) continue;
    Backend& backend = BackendById(id);
    EXPECT_EQ(backend.info().min_threads, 1) << id;
    EXPECT_EQ(backend.info().threads, 2) << id;
    auto prepared = backend.Prepare(mesh);
    ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
    std::vector<float> positions(3 * 1001, std::nanf(""));
    const SkinFrame frame{.palette = palette, .positions = positions, .threads = 1};
    ASSERT_TRUE(backend.Skin(**prepared, frame).ok()) << id;
    EXPECT_TRUE(CompareWithReference(*mesh, palette, positions, {}).within_tolerance()) << id;
  }
}

TEST(BackendListTest, OpenClBackendsAreAvailableOrSayWhyNot) {
  for (const char* id : {"opencl", "opencl-zerocopy"}) {
    const BackendInfo& info = BackendById(id).info();
    if (!info.available) {
      EXPECT_FALSE(info.unavailable_reason.empty()) << id;
      GTEST_SKIP() << id << " unavailable: " << info.unavailable_reason;
    }
  }
}

}  // namespace
}  // namespace skinserve::testing
