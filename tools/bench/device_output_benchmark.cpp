#include "device_output_benchmark.h"

#include <benchmark/benchmark.h>
#include <fmt/format.h>

#include <memory>

#include "backends/opencl/opencl_backends.h"
#include "backends/opencl/opencl_device_memory.h"
#include "backends/opencl/opencl_runtime.h"
#include "tick_counters.h"

namespace skinserve::bench {
namespace {

// The runtime and its backends live through the run (the rows point into them).
struct DeviceOutputBackends {
  std::shared_ptr<OpenClRuntime> runtime;
  std::vector<std::unique_ptr<Backend>> backends;
};

DeviceOutputBackends& Held() {
  static DeviceOutputBackends held;
  return held;
}

void SkinDeviceOutputBenchmark(benchmark::State& state, WorkloadCache* cache, Backend* backend,
                               OpenClRuntime* runtime, uint32_t vertices, uint32_t bones,
                               bool in_place) {
  const Workload& workload = cache->Get(vertices, bones);
  const PreparedMesh& prepared = cache->Prepared(*backend, vertices, bones);
  auto memory = CreateOpenClDeviceMemory(*runtime, backend->info().id, 12ull * vertices, in_place);
  if (!memory.ok()) {
    state.SkipWithError(memory.status().ToString().c_str());
    return;
  }
  std::size_t frame = 0;
  DeviceTiming device;
  int64_t kernel_ns = 0;
  for (auto _ : state) {
    SkinFrame skin{.palette = workload.palettes[frame++ % workload.palettes.size()],
                   .device_timing = &device};
    skin.device = {.memory = memory->get(), .positions_offset = 0};
    if (Status s = backend->Skin(prepared, skin); !s.ok()) {
      state.SkipWithError(s.ToString().c_str());
      return;
    }
    kernel_ns += device.kernel_ns;
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * vertices));
  state.counters["vertices_per_second"] =
      benchmark::Counter(vertices, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["bytes_per_vertex"] = BytesPerVertex(bones, false);
  if (state.iterations() > 0 && kernel_ns > 0) {  // 0: unprofiled (--opencl-device-timing=0)
    state.counters["kernel_ns"] =
        static_cast<double>(kernel_ns) / static_cast<double>(state.iterations());
  }
}

void SkinTickDeviceOutputBenchmark(benchmark::State& state, WorkloadCache* cache, Backend* backend,
                                   OpenClRuntime* runtime, uint32_t vertices, uint32_t bones,
                                   uint32_t characters) {
  std::vector<const PreparedMesh*> meshes;
  for (uint32_t c = 0; c < characters; ++c) {
    meshes.push_back(&cache->Prepared(*backend, vertices, bones, false, RestEncoding::kFloat32, c));
  }
  const Workload& workload = cache->Get(vertices, bones);
  const uint64_t array = 12ull * vertices;
  auto memory = CreateOpenClDeviceMemory(*runtime, backend->info().id, array * characters, false);
  if (!memory.ok()) {
    state.SkipWithError(memory.status().ToString().c_str());
    return;
  }
  std::vector<SkinFrame> frames(characters);
  std::vector<Status> statuses(characters);
  std::size_t frame = 0;
  for (auto _ : state) {
    const auto& palette = workload.palettes[frame++ % workload.palettes.size()];
    for (uint32_t c = 0; c < characters; ++c) {
      frames[c] = {.palette = palette};
      frames[c].device = {.memory = memory->get(), .positions_offset = c * array};
    }
    backend->SkinFrames(meshes, frames, statuses);
    for (const Status& s : statuses) {
      if (!s.ok()) return state.SkipWithError(s.ToString().c_str());
    }
  }
  SetTickCounters(state, characters, vertices);
}

}  // namespace

bool RegisterDeviceOutputRows(WorkloadCache& cache, const std::vector<uint32_t>& vertices,
                              const std::vector<uint32_t>& bones, int threads,
                              const std::string& opencl_device, bool device_timing, uint32_t tick) {
  auto runtime = OpenClRuntime::Create(
      {.threads = threads, .device = opencl_device, .device_timing = device_timing});
  if (!runtime.ok()) {
    fmt::print(stderr, "skinserve-bench: --device-output: {}\n", runtime.status().ToString());
    return false;
  }
  DeviceOutputBackends& held = Held();
  held.runtime = *runtime;
  held.backends = MakeOpenClBackendsOn(held.runtime);
  Backend& opencl = *held.backends.front();
  if (opencl.info().id != "opencl" || !opencl.info().available) {
    fmt::print(stderr, "skinserve-bench: --device-output: {}\n", opencl.info().unavailable_reason);
    return false;
  }
  for (uint32_t v : vertices) {
    for (uint32_t b : bones) {
      for (const bool in_place : {false, true}) {
        const char* name = in_place ? "BM_SkinDeviceOutputInPlace" : "BM_SkinDeviceOutput";
        benchmark::RegisterBenchmark(fmt::format("{}/opencl/{}/{}", name, v, b).c_str(),
                                     SkinDeviceOutputBenchmark, &cache, &opencl, held.runtime.get(),
                                     v, b, in_place)
            ->UseRealTime()
            ->Unit(benchmark::kMicrosecond);
      }
      if (tick > 0) {
        benchmark::RegisterBenchmark(
            fmt::format("BM_SkinTickDeviceOutput/opencl/{}/{}/characters:{}", v, b, tick).c_str(),
            SkinTickDeviceOutputBenchmark, &cache, &opencl, held.runtime.get(), v, b, tick)
            ->UseRealTime()
            ->Unit(benchmark::kMillisecond);
      }
    }
  }
  return true;
}

}  // namespace skinserve::bench
