// The engine's steady-state frame path allocates nothing: a reused SkinJob submitted
// frame after frame makes no heap allocation on any thread, once warm. Counted by
// replacing the global operator new in this test binary (it only counts).
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <future>
#include <new>

#include "cpu_backend_ids.h"
#include "skinserve/engine/engine.h"
#include "skinserve/reference/synthetic.h"

namespace {
std::atomic<long> allocations{0};
}  // namespace

void* operator new(std::size_t size) {
  allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace skinserve {
namespace {

class CountingJob final : public SkinJob {
 public:
  std::promise<Status>* done = nullptr;

 private:
  void OnSkinned(Status status, const FrameTiming&) override { done->set_value(status); }
};

TEST(EngineAllocationTest, AReusedJobAllocatesNothingPerFrame) {
  auto engine =
      Engine::Create({.compute_threads = 2,
                      .enabled_backends = {"serial", kSimdTestBackend, kSimdOpenMpTestBackend}})
          .value();
  const auto info = engine->AddMesh(MakeSyntheticMesh({.vertex_count = 120'000})).value();
  const std::vector<float> palettes = [&] {
    std::vector<float> p;
    for (int i = 0; i < 3; ++i) {
      const auto one = MakeSyntheticPalette(info.joint_count, 3, i);
      p.insert(p.end(), one.begin(), one.end());
    }
    return p;
  }();
  std::vector<float> positions(3ull * info.vertex_count * 3);
  {  // The counter sees allocations: the callback form allocates its job.
    SkinRequest request{info.id,
                        "serial",
                        std::span(palettes).first(12ull * info.joint_count),
                        1,
                        std::span(positions).first(3ull * info.vertex_count),
                        {}};
    const long before = allocations.load();
    ASSERT_TRUE(engine->SkinBlocking(request).ok());
    EXPECT_GT(allocations.load(), before);
  }
  for (const char* backend : {"serial", kSimdTestBackend, kSimdOpenMpTestBackend}) {
    for (uint32_t instances : {1u, 3u}) {
      SCOPED_TRACE(::testing::Message() << backend << " K=" << instances);
      CountingJob job;
      job.request.mesh_id = info.id;
      job.request.backend = backend;
      job.request.instances = instances;
      job.request.palette = std::span(palettes).first(12ull * info.joint_count * instances);
      job.request.positions = std::span(positions).first(3ull * info.vertex_count * instances);
      std::promise<Status> promises[6];
      long during = 0;
      for (int frame = 0; frame < 6; ++frame) {
        job.done = &promises[frame];
        std::future<Status> result = promises[frame].get_future();
        const long before = allocations.load();
        ASSERT_TRUE(engine->Submit(&job).ok());
        const Status status = result.get();
        if (frame >= 3) during += allocations.load() - before;  // after warm-up
        ASSERT_TRUE(status.ok()) << status.ToString();
      }
      EXPECT_EQ(during, 0) << "heap allocations in three warm frames";
    }
  }
}

}  // namespace
}  // namespace skinserve
