// What a frame's preparation costs the server on its stream's kept plan against a plan
// built afresh (docs/serving/frame-profile.md#stream-plan): FrameJob::Prepare for a 25k x 2
// frame (77 joints, positions only), then the job let go of, no skinning. "kept": every
// frame has its stream's settings; "built": two meshes alternate, so every frame plans
// anew (what a shared-memory stream alternating offsets paid before the offset left the
// plan's key).
#include <benchmark/benchmark.h>

#include <memory>

#include "frames/frame_job.h"
#include "frames/stream_plan.h"
#include "skinserve/engine/engine.h"
#include "skinserve/reference/synthetic.h"
#include "skinserve/wire/conversions.h"

namespace skinserve {
namespace {

using server::FrameJob;
using server::StreamPlan;

constexpr uint32_t kJoints = 77;

class NoListener final : public FrameJob::Listener {
 public:
  void OnFrameDone(server::StreamAnswer*) override {}
  void OnPartsReady(server::StreamAnswer*) override {}
  void HoldForWire() override {}
  void ReleaseForWire() override {}
};

void PrepareFrames(benchmark::State& state, bool alternate_meshes) {
  auto engine = Engine::Create({.compute_threads = 1, .enabled_backends = {"simd"}});
  if (!engine.ok()) {
    state.SkipWithError(engine.status().ToString().c_str());
    return;
  }
  std::string meshes[2];
  for (int m = 0; m < 2; ++m) {
    auto info = (*engine)->AddMesh(MakeSyntheticMesh(
        {.vertex_count = 25000, .influences = 2, .joint_count = kJoints, .seed = 1u + m}));
    if (!info.ok()) {
      state.SkipWithError(info.status().ToString().c_str());
      return;
    }
    meshes[m] = info->id;
  }
  const std::string palette = wire::EncodeFloats(MakeSyntheticPalette(kJoints, 7, 0));
  server::InflightBudget budget(1ull << 30);
  NoListener listener;
  FrameJob job(&listener, &budget);
  StreamPlan plan;
  v1::SkinRequest request;
  uint64_t frame = 0;
  for (auto _ : state) {
    request.set_mesh_id(meshes[alternate_meshes ? frame % 2 : 0]);
    request.set_frame(frame++);
    request.set_palette(palette);
    Status s = job.Prepare(request, **engine, "simd", server::RegionCaller{}, &plan);
    if (!s.ok()) {
      state.SkipWithError(s.ToString().c_str());
      return;
    }
    job.Fail(Internal("not skinned"));  // lets go of the mesh, as a frame's end does
  }
  state.counters["builds"] = static_cast<double>(plan.builds());
}

void BM_PrepareOnKeptPlan(benchmark::State& state) { PrepareFrames(state, false); }
void BM_PrepareOnBuiltPlan(benchmark::State& state) { PrepareFrames(state, true); }
BENCHMARK(BM_PrepareOnKeptPlan)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PrepareOnBuiltPlan)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace skinserve

BENCHMARK_MAIN();
