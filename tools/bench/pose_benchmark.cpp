#include "pose_benchmark.h"

#include <benchmark/benchmark.h>
#include <fmt/format.h>

#include <vector>

#include "skinserve/animation/blending_job.h"
#include "skinserve/animation/local_to_model_job.h"
#include "skinserve/animation/palette_job.h"
#include "skinserve/animation/sampling_job.h"
#include "skinserve/animation/synthetic_rig.h"
#include "skinserve/character/gltf_import.h"
#include "skinserve/character/rig.h"

namespace skinserve::bench {
namespace {

using namespace skinserve::animation;

// A glTF character's skin 0 and first clip as the runtime takes them.
Result<SyntheticRig> GltfRig(const std::string& path) {
  auto character = LoadGltfFile(path);
  if (!character.ok()) return character.status();
  if (character->skins.empty() || character->clips.empty()) {
    return InvalidArgument(path + " has no skin or no clip");
  }
  auto rig = RigFromSkin(*character, 0);
  if (!rig.ok()) return rig.status();
  return SyntheticRig{rig->skeleton, RawClipFromCharacter(character->clips[0], *rig)};
}

// Two layers (t and t + 0.7 s, weights 0.3 and 0.7) sampled, blended, local-to-model and
// palette; one layer when !blend. Time moves 1/60 s an iteration, each layer keeping its
// SamplingContext, as a character played at 60 Hz. The clip is stored to `max_error_mm`
// (0: the default, 16-bit keys; looser: packed keys).
void PoseBenchmark(benchmark::State& state, const SyntheticRig& rig, bool blend,
                   float max_error_mm = 0) {
  const uint32_t joints = rig.skeleton.joint_count();
  auto built = BuildCompactClip(rig.clip, rig.skeleton, {max_error_mm});
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
          fmt::format("{}/{}", blend ? "BM_Pose" : "BM_PoseOneClip", joints).c_str(),
          [joints, blend](benchmark::State& state) {
            PoseBenchmark(state, MakeSyntheticRig(joints), blend);
          })
          ->Unit(benchmark::kMicrosecond);
    }
  }
  // The repository's glTF test character (its 19-joint skin and 2 s walk; no 67-77 joint
  // character is in the repository), read from the source tree this binary was built from.
  for (bool blend : {true, false}) {
    benchmark::RegisterBenchmark(
        blend ? "BM_Pose/CesiumMan" : "BM_PoseOneClip/CesiumMan",
        [blend](benchmark::State& state) {
          auto rig = GltfRig(SKINSERVE_SOURCE_DIR "/tests/assets/gltf/CesiumMan.glb");
          if (!rig.ok()) {
            state.SkipWithError(rig.status().ToString().c_str());
            return;
          }
          PoseBenchmark(state, *rig, blend);
        })
        ->Unit(benchmark::kMicrosecond);
  }
  // The same two-layer poses with clips stored to 1 mm (packed keys: what a looser bound
  // costs the sampler; docs/serving/animation-runtime.md#size).
  benchmark::RegisterBenchmark("BM_Pose/77/1mm", [](benchmark::State& state) {
    PoseBenchmark(state, MakeSyntheticRig(77), true, 1.0f);
  })->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("BM_Pose/CesiumMan/1mm", [](benchmark::State& state) {
    auto rig = GltfRig(SKINSERVE_SOURCE_DIR "/tests/assets/gltf/CesiumMan.glb");
    if (!rig.ok()) {
      state.SkipWithError(rig.status().ToString().c_str());
      return;
    }
    PoseBenchmark(state, *rig, true, 1.0f);
  })->Unit(benchmark::kMicrosecond);
}

}  // namespace skinserve::bench
