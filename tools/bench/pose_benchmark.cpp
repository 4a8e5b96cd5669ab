#include "pose_benchmark.h"

#include <benchmark/benchmark.h>
#include <fmt/format.h>

#include <vector>

#include "skinserve/animation/blending_job.h"
#include "skinserve/animation/local_to_model_job.h"
#include "skinserve/animation/palette_job.h"
#include "skinserve/animation/sampling_job.h"
#include "skinserve/animation/synthetic_rig.h"

namespace skinserve::bench {
namespace {

using namespace skinserve::animation;

void PoseBenchmark(benchmark::State& state, uint32_t joints, bool blend) {
  const SyntheticRig rig = MakeSyntheticRig(joints);
  auto built = BuildCompactClip(rig.clip, rig.skeleton);
  if (!built.ok()) {
    state.SkipWithError(built.status().ToString().c_str());
    return;
  }
  const CompactClip& clip = *built;
  std::vector<Transform> a(joints), b(joints), blended(joints);
  std::vector<float> wa(clip.weight_count), wb(clip.weight_count), weights(clip.weight_count);
  std::vector<Affine> model(joints);
  std::vector<float> palette(12ull * rig.skeleton.palette_size());
  SamplingContext context_a, context_b;  // one a layer, as a character playing two clips
  float t = 0;
  for (auto _ : state) {
    Status s = SamplingJob{&rig.skeleton, &clip, t, TimeMode::kLoop, a, wa, &context_a}.Run();
    std::span<const Transform> local = a;
    if (blend && s.ok()) {
      s = SamplingJob{&rig.skeleton, &clip, t + 0.7f, TimeMode::kLoop, b, wb, &context_b}.Run();
      const BlendLayer layers[] = {{a, 0.3f, false, wa}, {b, 0.7f, false, wb}};
      if (s.ok()) s = BlendingJob{layers, blended, weights}.Run();
      local = blended;
    }
    if (s.ok()) s = LocalToModelJob{&rig.skeleton, local, model}.Run();
    if (s.ok()) s = PaletteJob{&rig.skeleton, model, palette}.Run();
    if (!s.ok()) {
      state.SkipWithError(s.ToString().c_str());
      break;
    }
    benchmark::DoNotOptimize(palette.data());
    benchmark::ClobberMemory();
    t += 1.0f / 60;
  }
  // A label, not counters: Google Benchmark's CSV output needs every row to carry the same
  // counters, and the skinning rows have none of these.
  state.SetLabel(fmt::format("joints={} clip_bytes={}", joints, clip.Serialize().size()));
}

}  // namespace

void RegisterPoseBenchmarks() {
  for (uint32_t joints : {67u, 77u}) {
    for (bool blend : {true, false}) {
      benchmark::RegisterBenchmark(
          fmt::format("{}/{}", blend ? "BM_Pose" : "BM_PoseOneClip", joints).c_str(), PoseBenchmark,
          joints, blend)
          ->Unit(benchmark::kMicrosecond);
    }
  }
}

}  // namespace skinserve::bench
