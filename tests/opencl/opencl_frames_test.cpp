// Frame after frame on one prepared mesh (the copying backend reuses its device buffers,
// the zero-copy one wraps new host memory each frame): every result must follow its own
// palette. And frames from several threads at once, on one prepared mesh and across both
// backends (one shared queue and kernel objects): all correct, none mixed up.
#include <gtest/gtest.h>

#include <limits>
#include <mutex>
#include <thread>

#include "opencl_test_support.h"
#include "skinserve/reference/synthetic.h"

namespace skinserve::testing {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

class OpenClFramesTest : public ::testing::TestWithParam<std::string> {};

TEST_P(OpenClFramesTest, EveryFrameFollowsItsPalette) {
  Backend& backend = OpenClBackend(GetParam());
  SKIP_IF_OPENCL_UNAVAILABLE(backend);
  constexpr uint32_t kVertices = 20011, kJoints = 77;
  auto mesh = SyntheticMesh(kVertices, 3, kJoints, true, 11);
  auto prepared = backend.Prepare(mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  // The same output buffers every frame, as a client streaming frames would have.
  std::vector<float> positions(3 * kVertices), normals(3 * kVertices);
  for (uint64_t frame = 0; frame < 40; ++frame) {
    std::fill(positions.begin(), positions.end(), kNaN);
    std::fill(normals.begin(), normals.end(), kNaN);
    const auto palette =
        frame % 10 == 9 ? MakeIdentityPalette(kJoints) : MakeSyntheticPalette(kJoints, 11, frame);
    // Every third frame skips normals: the other kernel, the same prepared mesh.
    const bool with_normals = frame % 3 != 2;
    const std::span<float> normals_out =
        with_normals ? std::span<float>(normals) : std::span<float>();
    ASSERT_TRUE(backend.Skin(**prepared, {palette, positions, normals_out}).ok());
    ASSERT_EQ(ReferenceMismatch(*mesh, palette, positions, normals_out), "") << "frame " << frame;
  }
}

TEST_P(OpenClFramesTest, ConcurrentFramesOnOnePreparedMeshAreAllCorrect) {
  Backend& backend = OpenClBackend(GetParam());
  SKIP_IF_OPENCL_UNAVAILABLE(backend);
  constexpr uint32_t kVertices = 30007, kJoints = 77;
  constexpr int kThreads = 4, kFramesPerThread = 12;
  auto mesh = SyntheticMesh(kVertices, 4, kJoints, true, 23);
  auto prepared = backend.Prepare(mesh);
  ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
  std::mutex failures_mutex;
  std::vector<std::string> failures;
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      std::vector<float> positions(3 * kVertices), normals(3 * kVertices);
      for (int f = 0; f < kFramesPerThread; ++f) {
        std::fill(positions.begin(), positions.end(), kNaN);
        std::fill(normals.begin(), normals.end(), kNaN);
        // A palette no other thread uses: a frame mixed up with another shows.
        const auto palette = MakeSyntheticPalette(kJoints, 23, 100 * t + f);
        Status status = backend.Skin(**prepared, {palette, positions, normals});
        std::string mismatch =
            status.ok() ? ReferenceMismatch(*mesh, palette, positions, normals) : status.ToString();
        if (!mismatch.empty()) {
          std::lock_guard lock(failures_mutex);
          failures.push_back("thread " + std::to_string(t) + " frame " + std::to_string(f) + ": " +
                             mismatch);
        }
      }
    });
  }
  for (auto& thread : threads) thread.join();
  EXPECT_TRUE(failures.empty()) << failures.size() << " failed, first: " << failures.front();
}

INSTANTIATE_TEST_SUITE_P(OpenCl, OpenClFramesTest, ::testing::ValuesIn(OpenClBackendIds()),
                         BackendTestName);

// Both backends share one queue and one set of kernel objects: frames of both at once,
// on different meshes (different influence counts: different kernels), all correct.
TEST(OpenClSharedRuntimeTest, BothBackendsConcurrentlyOnDifferentMeshes) {
  for (const auto& backend : OpenClBackends()) SKIP_IF_OPENCL_UNAVAILABLE(*backend);
  struct Work {
    Backend* backend;
    std::shared_ptr<const Mesh> mesh;
    std::unique_ptr<PreparedMesh> prepared;
    bool normals;
  };
  std::vector<Work> work;
  uint32_t b = 1;
  for (const std::string& id : OpenClBackendIds()) {
    for (bool normals : {false, true}) {
      Backend& backend = OpenClBackend(id);
      auto mesh = SyntheticMesh(9973 + b, b, 77, normals, b);
      auto prepared = backend.Prepare(mesh);
      ASSERT_TRUE(prepared.ok()) << prepared.status().ToString();
      work.push_back({&backend, mesh, std::move(prepared).value(), normals});
      b = b % 7 + 2;  // 1, 3, 5, 7, 2, 4, ...: different kernels
    }
  }
  std::mutex failures_mutex;
  std::vector<std::string> failures;
  std::vector<std::thread> threads;
  for (std::size_t w = 0; w < work.size(); ++w) {
    threads.emplace_back([&, w] {
      const Work& job = work[w];
      const uint32_t v = job.mesh->vertex_count();
      std::vector<float> positions(3 * v), normals(job.normals ? 3 * v : 0);
      for (uint64_t f = 0; f < 10; ++f) {
        std::fill(positions.begin(), positions.end(), kNaN);
        std::fill(normals.begin(), normals.end(), kNaN);
        const auto palette = MakeSyntheticPalette(77, w, f);
        Status status = job.backend->Skin(*job.prepared, {palette, positions, normals});
        std::string mismatch = status.ok()
                                   ? ReferenceMismatch(*job.mesh, palette, positions, normals)
                                   : status.ToString();
        if (!mismatch.empty()) {
          std::lock_guard lock(failures_mutex);
          failures.push_back(job.backend->info().id +
                             " B=" + std::to_string(job.mesh->influences()) + " frame " +
                             std::to_string(f) + ": " + mismatch);
        }
      }
    });
  }
  for (auto& thread : threads) thread.join();
  EXPECT_TRUE(failures.empty()) << failures.size() << " failed, first: " << failures.front();
}

}  // namespace
}  // namespace skinserve::testing
