// skinserve-bench: Backend::Skin timed per backend over the paper's grid, plus the
// machine's memory bandwidth, so each figure can be read against its physical bound.
//
//   skinserve-bench                    every benchmark, Google Benchmark's usual output
//   skinserve-bench --paper-tables     the grid (positions only), medians of 3, then the
//                                      paper's tables 2 and 3 layout
// Filters: --backends=a,b  --vertices=25000,100000  --bones=1,2  --normals (paper tables
// with normals too). --methods=linear,dual-quaternion: the skinning methods to time
// (default linear; dual quaternions on rigid palettes, rows BM_SkinDualQuaternion and
// BM_SkinNormalsDualQuaternion beside BM_Skin and BM_SkinNormals). --opencl-device=gpu (cpu, gpu or
// part of a platform or device name, as skinserve's option). --streams=N: the OpenCL backends also
// with N threads skinning at once (BM_SkinStreams), frames of several streams in flight on the
// device. --morph: also BM_SkinMorph[Normals]/<backend>/<vertices>/<bones>/active:0 and
// active:4, the same mesh with 64 morph targets each moving 10% of the vertices, frames with
// no and with 4 active targets, beside the skin-only rows (issue 28's 1.3x target).
// --tangents: also BM_SkinTangents[DualQuaternion]/<backend>/<vertices>/<bones>, normals and
// tangents (4 floats a vertex) skinned together, beside BM_SkinNormals (with --quantized,
// BM_SkinTangentsQuantized[Weights8] too).
// --opencl-global-palette: `opencl` once more, from a second runtime whose kernels read the
// palette from global memory (rows .../opencl-global/...), beside `opencl`'s own rows, which
// on a GPU stage it in work-group local memory: the two kernels compared in one run.
// --quantized: also BM_SkinQuantized/<backend>/<vertices>/<bones> (and
// BM_SkinQuantizedWeights8) for the backends that read a quantized rest stream (simd,
// simd-openmp and OpenCL; RestEncoding quantized16, quantized8-weights), the same mesh
// stored quantized, beside the float rows; after the run, each quantized row's bytes per
// vertex, its share of BM_MemoryBandwidth's bound and its speed over the float row (issue 29).
// --encoding=float16,snorm16: also BM_Skin[Normals]Encoded<Encoding>/<backend>/<vertices>/<bones>
// (and, with --streams=N, BM_SkinStreamsEncoded<Encoding>/...) for the backends that write
// that encoding themselves (BackendInfo::encoded_outputs: the OpenCL ones encode on the
// device and read back only the encoded bytes), beside the float rows (issue 29 item 2);
// each row reports read_back_bytes_per_vertex (12 a float frame's positions, 6 encoded);
// and BM_Skin[Normals]HostEncoded<Encoding>/... for every backend, the baseline: float32
// skinned, then encoded by core/encoding as the server does for the other backends.
// --process-cpu-time: those rows' CPU time is the process's (every thread's, OpenMP's
// workers included), not the timing thread's alone.
// --vertex-order=sorted: the synthetic meshes' vertices sorted by their joints, as a mesh
// optimiser leaves a real character (neighbouring vertices share bones), instead of the
// paper's shuffled order (each vertex on a random bone); the CPU loops hardly care, a GPU's
// palette reads do.
// --tick=N: also BM_SkinTick[Normals]/<backend>/<vertices>/<bones>/characters:N, a tick's
// work on one thread: N distinct meshes (as many characters, each mesh its own seed) skinned
// one after another into their ranges of one output, as a tick fills a region; the meshes and
// the output (N x (30 + 24) bytes a vertex at 25k x 2 with normals) outgrow the caches, where
// BM_Skin's single mesh stays in them. Reports seconds_per_character beside the cached row;
// with --quantized also BM_SkinTick[Normals]Quantized/... (RestEncoding quantized16); for
// backends that skin frames together (`opencl`) also BM_SkinTickTogether[Normals]/..., the
// same tick handed over at once (Backend::SkinFrames: tick launches), and with
// --device-output BM_SkinTickDeviceOutput/opencl/..., that tick into device memory.
// --tick-slots=K (with --tick): each tick into the next of K outputs in turn (the rows gain
// /slots:K), as the service's regions hold one slot per tick in flight for every stream: 6
// streams of 64 characters with 2 ticks in flight write 12 x 19 MB in turn (230 MB), where
// one output of 19 MB may stay in the L3.
// --tick-gap-us=U (with --tick): a pause of U microseconds after each tick, left out of the
// timing (the rows gain /gap_us:U), as a service's ticks arrive a period apart (16,667 at
// 60 ticks/s) and the caches and the core's clock may cool between them.
// --device-output: also BM_SkinDeviceOutput/opencl/<vertices>/<bones> (and
// BM_SkinDeviceOutputInPlace)
// (device_output_benchmark.h), `opencl`'s frame with its output left in device memory, the
// GPU regions' path: Figure 5's fourth curve beside BM_Skin/opencl, read back.
// BM_Pose/<joints> and BM_PoseOneClip/<joints> (pose_benchmark.h): the animation runtime's
// frame for one character, sampling to palette, on the timing thread alone (issue 43).
// Other flags go to Google Benchmark (e.g. --benchmark_min_time=0.5).
//
// OpenCL backends report per frame, from profiling events, the device's kernel_ns and
// transfer_ns, kernel_vertices_per_second and kernel_bytes_per_second (kernel only,
// bytes_per_vertex each); with --opencl-device-timing=0 their queues are unprofiled, as the
// server runs them by default (none of those, and a small frame without profiling's cost).
// The device's bounds are measured in the same run:
// BM_PcieHostToDevice, BM_PcieDeviceToHost (pinned memory) and BM_DeviceMemoryCopy (device
// to device, read + write). kernel_bytes_per_second over BM_DeviceMemoryCopy's
// bytes_per_second is the kernel's share of the device copy bound, which the console output
// prints after the runs ("% mem", OpenCL device against its bounds).
// Run it on an otherwise idle machine: with another process on a core, libgomp's default
// spin-wait makes the OpenMP backends' frames wait for a 4 ms scheduler tick (wall time
// twice the CPU time); OMP_WAIT_POLICY=passive limits that, at some cost on small frames.
#include <benchmark/benchmark.h>
#include <fmt/format.h>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <exception>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>

#include "backends/opencl/opencl_backends.h"
#include "backends/opencl/opencl_runtime.h"
#include "device_output_benchmark.h"
#include "paper_tables.h"
#include "pose_benchmark.h"
#include "skinserve/engine/backend_registry.h"
#include "skinserve/model/aligned_buffer.h"
#include "skinserve/reference/synthetic_morph.h"
#include "tick_counters.h"
#include "workload_cache.h"

namespace skinserve::bench {
namespace {

struct Options {
  bool paper_tables = false;
  bool normals_in_tables = false;
  std::vector<std::string> backends;
  std::vector<uint32_t> vertices = {25'000, 100'000, 400'000, 1'600'000};
  std::vector<uint32_t> bones = {1, 2, 3, 4};
  std::string opencl_device;
  int streams = 1;
  std::vector<SkinningMethod> methods = {SkinningMethod::kLinear};
  bool morph = false;
  bool tangents = false;
  bool opencl_global_palette = false;
  bool quantized = false;
  std::vector<VertexEncoding> encodings;  // --encoding=: encoded-output rows
  bool process_cpu_time = false;          // --process-cpu-time: those rows' CPU time, all threads
  bool sorted_by_joints = false;          // --vertex-order=sorted
  bool device_output = false;             // --device-output: BM_SkinDeviceOutput rows
  bool opencl_device_timing = true;       // --opencl-device-timing=0: unprofiled queues
  uint32_t tick = 0;                      // --tick=N: BM_SkinTick rows of N characters
  uint32_t tick_slots = 1;                // --tick-slots=K: their outputs, used in turn
  uint32_t tick_gap_us = 0;               // --tick-gap-us=U: an untimed pause after each tick
};

template <typename T>
std::vector<T> ParseList(const std::string& s) {
  std::vector<T> out;
  std::stringstream stream(s);
  for (std::string item; std::getline(stream, item, ',');) {
    if constexpr (std::is_same_v<T, std::string>) {
      out.push_back(item);
    } else {
      out.push_back(static_cast<T>(std::stoul(item)));
    }
  }
  return out;
}

// Takes our flags out of argv, leaving Google Benchmark's.
Options ParseOptions(int* argc, char** argv) {
  Options options;
  int kept = 1;
  for (int i = 1; i < *argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&](const char* prefix) -> const char* {
      return arg.rfind(prefix, 0) == 0 ? argv[i] + std::strlen(prefix) : nullptr;
    };
    if (arg == "--paper-tables") {
      options.paper_tables = true;
    } else if (arg == "--morph") {
      options.morph = true;
    } else if (arg == "--tangents") {
      options.tangents = true;
    } else if (arg == "--opencl-global-palette") {
      options.opencl_global_palette = true;
    } else if (arg == "--quantized") {
      options.quantized = true;
    } else if (arg == "--device-output") {
      options.device_output = true;
    } else if (arg == "--normals") {
      options.normals_in_tables = true;
    } else if (const char* list = value("--backends=")) {
      options.backends = ParseList<std::string>(list);
    } else if (const char* counts = value("--vertices=")) {
      options.vertices = ParseList<uint32_t>(counts);
    } else if (const char* bones = value("--bones=")) {
      options.bones = ParseList<uint32_t>(bones);
    } else if (const char* device = value("--opencl-device=")) {
      options.opencl_device = device;
    } else if (const char* timing = value("--opencl-device-timing=")) {
      options.opencl_device_timing = std::string(timing) != "0";
    } else if (const char* streams = value("--streams=")) {
      options.streams = static_cast<int>(std::stoul(streams));
    } else if (const char* characters = value("--tick=")) {
      options.tick = static_cast<uint32_t>(std::stoul(characters));
    } else if (const char* slots = value("--tick-slots=")) {
      options.tick_slots = static_cast<uint32_t>(std::stoul(slots));
      if (options.tick_slots == 0) throw std::invalid_argument("--tick-slots=: at least 1");
    } else if (const char* gap = value("--tick-gap-us=")) {
      options.tick_gap_us = static_cast<uint32_t>(std::stoul(gap));
    } else if (arg == "--process-cpu-time") {
      options.process_cpu_time = true;
    } else if (const char* order = value("--vertex-order=")) {
      if (std::string_view(order) != "sorted" && std::string_view(order) != "shuffled") {
        throw std::invalid_argument(std::string("--vertex-order=: sorted or shuffled, not ") +
                                    order);
      }
      options.sorted_by_joints = std::string_view(order) == "sorted";
    } else if (const char* encodings = value("--encoding=")) {
      for (const std::string& name : ParseList<std::string>(encodings)) {
        const auto encoding = ParseVertexEncoding(name);
        if (!encoding || *encoding == VertexEncoding::kFloat32) {
          throw std::invalid_argument("--encoding=: float16 or snorm16, not " + name);
        }
        options.encodings.push_back(*encoding);
      }
    } else if (const char* methods = value("--methods=")) {
      options.methods.clear();
      for (const std::string& name : ParseList<std::string>(methods)) {
        const auto method = ParseMethod(name);
        if (!method) throw std::invalid_argument("--methods=: unknown method " + name);
        options.methods.push_back(*method);
      }
    } else {
      argv[kept++] = argv[i];
    }
  }
  *argc = kept;
  if (options.tick_slots > 1 && options.tick == 0) {
    throw std::invalid_argument("--tick-slots=: only with --tick=N");
  }
  if (options.tick_gap_us > 0 && options.tick == 0) {
    throw std::invalid_argument("--tick-gap-us=: only with --tick=N");
  }
  return options;
}

WorkloadCache& Cache() {
  static WorkloadCache cache;
  return cache;
}

// OpenCL rows: the device's kernel and transfer time per frame (profiling events), averaged
// over the frames and threads; false (nothing reported) for backends without device times.
bool ReportDeviceTimes(benchmark::State& state, const DeviceTiming& total) {
  if (total.kernel_ns <= 0 || state.iterations() <= 0) return false;
  const double frames = static_cast<double>(state.iterations());
  state.counters["kernel_ns"] = benchmark::Counter(static_cast<double>(total.kernel_ns) / frames,
                                                   benchmark::Counter::kAvgThreads);
  state.counters["transfer_ns"] = benchmark::Counter(
      static_cast<double>(total.transfer_ns) / frames, benchmark::Counter::kAvgThreads);
  return true;
}

void SkinBenchmark(benchmark::State& state, Backend* backend, uint32_t vertices, uint32_t bones,
                   bool normals, SkinningMethod method, RestEncoding rest, bool tangents) {
  const Workload& workload = Cache().Get(vertices, bones, false, rest);
  const auto& palettes =
      method == SkinningMethod::kDualQuaternion ? workload.rigid_palettes : workload.palettes;
  const PreparedMesh& prepared = Cache().Prepared(*backend, vertices, bones, false, rest);
  AlignedBuffer<float> positions(3ull * vertices), out_normals(normals ? 3ull * vertices : 0);
  AlignedBuffer<float> out_tangents(tangents ? 4ull * vertices : 0);
  std::size_t frame = state.thread_index();
  DeviceTiming device, total;
  for (auto _ : state) {
    const SkinFrame skin{.palette = palettes[frame++ % palettes.size()],
                         .positions = positions.span(),
                         .normals = out_normals.span(),
                         .tangents = out_tangents.span(),
                         .device_timing = &device,
                         .method = method};
    if (Status s = backend->Skin(prepared, skin); !s.ok()) {
      state.SkipWithError(s.ToString().c_str());
      break;
    }
    total.kernel_ns += device.kernel_ns;
    total.transfer_ns += device.transfer_ns;
    benchmark::DoNotOptimize(positions.data());
    benchmark::ClobberMemory();
  }
  // Items: summed over threads, over the run's real time (BM_SkinStreams).
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * vertices));
  state.counters["vertices_per_second"] =
      benchmark::Counter(vertices, benchmark::Counter::kIsIterationInvariantRate);
  // Quantized rows: what the rest stream really moves (quantized_rest.h).
  const double bytes = rest == RestEncoding::kFloat32
                           ? BytesPerVertex(bones, normals, tangents)
                           : StreamedBytesPerVertex(rest, bones, kPaperJoints, normals, tangents);
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations() * vertices * bytes));
  state.counters["bytes_per_vertex"] = bytes;
  if (ReportDeviceTimes(state, total)) {
    const double frames = static_cast<double>(state.iterations());
    const double kernel_rate = vertices * frames * 1e9 / static_cast<double>(total.kernel_ns);
    state.counters["kernel_vertices_per_second"] =
        benchmark::Counter(kernel_rate, benchmark::Counter::kAvgThreads);
    state.counters["kernel_bytes_per_second"] =
        benchmark::Counter(kernel_rate * bytes, benchmark::Counter::kAvgThreads);
  }
}

// The timing loop of the encoded rows: `skin_one` (a frame; its Status) once untimed (the
// first encoded frame builds the encoder's program and grows its buffers), then once per
// iteration, each followed by `after_timed_frame`; items and vertices_per_second counted.
// False, with the run skipped naming the error, when a frame fails.
template <typename SkinOne, typename AfterFrame>
bool TimeEncodedFrames(benchmark::State& state, uint32_t vertices, const void* output,
                       const SkinOne& skin_one, const AfterFrame& after_timed_frame) {
  if (Status s = skin_one(); !s.ok()) {
    state.SkipWithError(s.ToString().c_str());
    return false;
  }
  for (auto _ : state) {
    if (Status s = skin_one(); !s.ok()) {
      state.SkipWithError(s.ToString().c_str());
      return false;
    }
    after_timed_frame();
    benchmark::DoNotOptimize(output);
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * vertices));
  state.counters["vertices_per_second"] =
      benchmark::Counter(vertices, benchmark::Counter::kIsIterationInvariantRate);
  return true;
}

// A frame whose output the backend writes encoded (SkinFrame::encoded): the OpenCL backends
// read back only the encoded bytes.
void SkinEncodedBenchmark(benchmark::State& state, Backend* backend, uint32_t vertices,
                          uint32_t bones, bool normals, VertexEncoding encoding) {
  const Workload& workload = Cache().Get(vertices, bones, false);
  const PreparedMesh& prepared = Cache().Prepared(*backend, vertices, bones, false);
  const std::size_t bytes = EncodedBytes(encoding, vertices);
  AlignedBuffer<std::byte> positions(bytes), out_normals(normals ? bytes : 0);
  Bounds box;
  std::size_t frame = state.thread_index();
  DeviceTiming device, total;
  const auto skin_one = [&] {
    SkinFrame skin{.palette = workload.palettes[frame++ % workload.palettes.size()],
                   .device_timing = &device};
    skin.encoded = {.encoding = encoding,
                    .positions = positions.span(),
                    .normals = out_normals.span(),
                    .bounds = &box};
    return backend->Skin(prepared, skin);
  };
  const auto count_device_time = [&] {
    total.kernel_ns += device.kernel_ns;
    total.transfer_ns += device.transfer_ns;
  };
  if (!TimeEncodedFrames(state, vertices, positions.data(), skin_one, count_device_time)) return;
  state.counters["read_back_bytes_per_vertex"] =
      static_cast<double>(EncodedBytes(encoding, 1) * (normals ? 2 : 1));
  ReportDeviceTimes(state, total);
}

// The same frame the host's way, the baseline of the rows above: the backend skins float32
// (into arrays reused every frame, as the server's scratch), then core/encoding encodes it
// (the box for snorm16, positions, normals), as the server does for a backend that does not
// list the encoding.
void SkinHostEncodedBenchmark(benchmark::State& state, Backend* backend, uint32_t vertices,
                              uint32_t bones, bool normals, VertexEncoding encoding) {
  const Workload& workload = Cache().Get(vertices, bones, false);
  const PreparedMesh& prepared = Cache().Prepared(*backend, vertices, bones, false);
  const std::size_t bytes = EncodedBytes(encoding, vertices);
  AlignedBuffer<std::byte> positions(bytes), out_normals(normals ? bytes : 0);
  AlignedBuffer<float> floats(3ull * vertices), float_normals(normals ? 3ull * vertices : 0);
  std::size_t frame = state.thread_index();
  const auto skin_one = [&]() -> Status {
    const SkinFrame skin{.palette = workload.palettes[frame++ % workload.palettes.size()],
                         .positions = floats.span(),
                         .normals = float_normals.span()};
    if (Status s = backend->Skin(prepared, skin); !s.ok()) return s;
    Bounds box;
    if (QuantizedToBox(encoding)) {
      Result<Bounds> computed = ComputeBounds(floats.span());
      if (!computed.ok()) return computed.status();
      box = *computed;
    }
    if (Status s = EncodePositions(encoding, floats.span(), box, positions.span()); !s.ok()) {
      return s;
    }
    return normals ? EncodeNormals(encoding, float_normals.span(), out_normals.span())
                   : Status::Ok();
  };
  TimeEncodedFrames(state, vertices, positions.data(), skin_one, [] {});
}

// A frame of the morph workload with `active` targets (0: the frame carries no weights).
void SkinMorphBenchmark(benchmark::State& state, Backend* backend, uint32_t vertices,
                        uint32_t bones, bool normals, uint32_t active) {
  const Workload& workload = Cache().Get(vertices, bones, true);
  const PreparedMesh& prepared = Cache().Prepared(*backend, vertices, bones, true);
  std::vector<std::vector<MorphWeight>> weights;
  for (int frame = 0; frame < kPalettesPerWorkload; ++frame) {
    weights.push_back(MakeMorphWeights(kMorphTargets, active, 42, frame));
  }
  AlignedBuffer<float> positions(3ull * vertices), out_normals(normals ? 3ull * vertices : 0);
  std::size_t frame = 0;
  DeviceTiming device;
  int64_t kernel_ns = 0;  // OpenCL: the morph and skinning kernels together
  for (auto _ : state) {
    SkinFrame skin{.palette = workload.palettes[frame % workload.palettes.size()],
                   .positions = positions.span(),
                   .normals = out_normals.span(),
                   .device_timing = &device};
    skin.morph_weights = weights[frame++ % weights.size()];
    if (Status s = backend->Skin(prepared, skin); !s.ok()) {
      state.SkipWithError(s.ToString().c_str());
      break;
    }
    kernel_ns += device.kernel_ns;
    benchmark::DoNotOptimize(positions.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * vertices));
  state.counters["vertices_per_second"] =
      benchmark::Counter(vertices, benchmark::Counter::kIsIterationInvariantRate);
  if (kernel_ns > 0 && state.iterations() > 0) {
    state.counters["kernel_ns"] = benchmark::Counter(static_cast<double>(kernel_ns) /
                                                     static_cast<double>(state.iterations()));
  }
}

// A tick of `characters` distinct meshes (the cache's copies 0..characters-1, made and
// prepared once), each skinned into its range of one output; tick k into output k % slots,
// and `gap_us` microseconds of untimed pause after each.
void SkinTickBenchmark(benchmark::State& state, Backend* backend, uint32_t vertices, uint32_t bones,
                       bool normals, uint32_t characters, uint32_t slots, uint32_t gap_us,
                       RestEncoding rest) {
  std::vector<const PreparedMesh*> meshes;
  for (uint32_t c = 0; c < characters; ++c) {
    meshes.push_back(&Cache().Prepared(*backend, vertices, bones, false, rest, c));
  }
  const Workload& workload = Cache().Get(vertices, bones);  // its palettes
  const std::size_t floats = 3ull * vertices;
  const std::size_t tick_floats = floats * characters;
  AlignedBuffer<float> positions(tick_floats * slots);
  AlignedBuffer<float> out_normals(normals ? tick_floats * slots : 0);
  std::size_t frame = 0;
  for (auto _ : state) {
    const auto& palette = workload.palettes[frame % workload.palettes.size()];
    const std::size_t slot = tick_floats * (frame++ % slots);
    for (uint32_t c = 0; c < characters; ++c) {
      const std::size_t at = slot + c * floats;
      const SkinFrame skin{
          .palette = palette,
          .positions = positions.span().subspan(at, floats),
          .normals = normals ? out_normals.span().subspan(at, floats) : std::span<float>()};
      if (Status s = backend->Skin(*meshes[c], skin); !s.ok()) {
        return state.SkipWithError(s.ToString().c_str());
      }
    }
    benchmark::DoNotOptimize(positions.data());
    benchmark::ClobberMemory();
    if (gap_us > 0) {
      state.PauseTiming();
      std::this_thread::sleep_for(std::chrono::microseconds(gap_us));
      state.ResumeTiming();
    }
  }
  SetTickCounters(state, characters, vertices);
}

// BM_SkinTickTogether: the same tick as SkinTickBenchmark handed to the backend at once
// (Backend::SkinFrames), as the engine hands a tick's characters to a backend that skins
// frames together (`opencl`: tick launches, opencl_tick_launch.h).
void SkinTickTogetherBenchmark(benchmark::State& state, Backend* backend, uint32_t vertices,
                               uint32_t bones, bool normals, uint32_t characters) {
  std::vector<const PreparedMesh*> meshes;
  for (uint32_t c = 0; c < characters; ++c) {
    meshes.push_back(
        &Cache().Prepared(*backend, vertices, bones, false, RestEncoding::kFloat32, c));
  }
  const Workload& workload = Cache().Get(vertices, bones);
  const std::size_t floats = 3ull * vertices;
  AlignedBuffer<float> positions(floats * characters);
  AlignedBuffer<float> out_normals(normals ? floats * characters : 0);
  std::vector<SkinFrame> frames(characters);
  std::vector<Status> statuses(characters);
  std::size_t frame = 0;
  for (auto _ : state) {
    const auto& palette = workload.palettes[frame++ % workload.palettes.size()];
    for (uint32_t c = 0; c < characters; ++c) {
      frames[c] = {
          .palette = palette,
          .positions = positions.span().subspan(c * floats, floats),
          .normals = normals ? out_normals.span().subspan(c * floats, floats) : std::span<float>()};
    }
    backend->SkinFrames(meshes, frames, statuses);
    for (const Status& s : statuses) {
      if (!s.ok()) return state.SkipWithError(s.ToString().c_str());
    }
    benchmark::DoNotOptimize(positions.data());
    benchmark::ClobberMemory();
  }
  SetTickCounters(state, characters, vertices);
}

// The device's bounds, measured with the runtime the OpenCL backends use (a second one
// on the same device): PCIe each way between pinned host memory and the device, and a
// device-to-device copy (bytes read + written).
enum class DeviceBound { kHostToDevice, kDeviceToHost, kDeviceCopy, kPinnedCopyOut };

void DeviceBandwidth(benchmark::State& state, OpenClRuntime* runtime, DeviceBound bound) {
  const std::size_t bytes = bound == DeviceBound::kDeviceCopy ? (512ull << 20) : (64ull << 20);
  auto lane = runtime->AcquireLane();
  auto device = runtime->CreateBuffer("bandwidth", CL_MEM_READ_WRITE, bytes, nullptr);
  auto target = runtime->CreateBuffer("bandwidth target", CL_MEM_READ_WRITE, bytes, nullptr);
  PinnedBuffer pinned;
  Status grown = runtime->GrowPinned(lane->compute, "bandwidth pinned", bytes, &pinned);
  if (!device.ok() || !target.ok() || !grown.ok()) {
    state.SkipWithError("cannot allocate the bandwidth buffers");
    return;
  }
  std::memset(pinned.host, 1, bytes);
  cl_int err = clEnqueueWriteBuffer(lane->compute, device->get(), CL_TRUE, 0, bytes, pinned.host, 0,
                                    nullptr, nullptr);
  for (auto _ : state) {
    switch (bound) {
      case DeviceBound::kHostToDevice:
        err |= clEnqueueWriteBuffer(lane->compute, device->get(), CL_FALSE, 0, bytes, pinned.host,
                                    0, nullptr, nullptr);
        break;
      case DeviceBound::kDeviceToHost:
        err |= clEnqueueReadBuffer(lane->compute, device->get(), CL_FALSE, 0, bytes, pinned.host, 0,
                                   nullptr, nullptr);
        break;
      case DeviceBound::kDeviceCopy:
        err |= clEnqueueCopyBuffer(lane->compute, device->get(), target->get(), 0, 0, bytes, 0,
                                   nullptr, nullptr);
        break;
      case DeviceBound::kPinnedCopyOut: {
        // What the copy backend's copy-out can do: pinned memory to pageable, threads
        // as in the benchmark's argument.
        static AlignedBuffer<char> pageable(bytes);
        const int threads = static_cast<int>(state.range(0));
        const std::size_t piece = bytes / threads;
#pragma omp parallel for num_threads(threads) schedule(static)
        for (int t = 0; t < threads; ++t) {
          std::memcpy(pageable.data() + t * piece, static_cast<char*>(pinned.host) + t * piece,
                      piece);
        }
        benchmark::ClobberMemory();
        break;
      }
    }
    err |= clFinish(lane->compute);
  }
  if (err != CL_SUCCESS) state.SkipWithError("an OpenCL transfer failed");
  clEnqueueUnmapMemObject(lane->compute, pinned.buffer.get(), pinned.host, 0, nullptr, nullptr);
  clFinish(lane->compute);
  const double moved = bound == DeviceBound::kDeviceCopy ? 2.0 * bytes : bytes;
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations() * moved));
}

// STREAM-style scaled copy over 256 MB on every core: what memory can move, read + write.
void MemoryBandwidth(benchmark::State& state) {
  constexpr std::size_t kFloats = 64ull << 20;
  static AlignedBuffer<float> source(kFloats), target(kFloats);
  const int threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
#pragma omp parallel for num_threads(threads) schedule(static)
  for (std::size_t i = 0; i < kFloats; ++i) source[i] = 1.0f, target[i] = 0.0f;  // first touch
  for (auto _ : state) {
    float* out = target.data();
    const float* in = source.data();
#pragma omp parallel for num_threads(threads) schedule(static)
    for (std::size_t i = 0; i < kFloats; ++i) out[i] = 1.0001f * in[i];
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations() * 2 * kFloats * sizeof(float)));
}

// Parses the command line into `options`; false, the error printed, on a bad value.
bool ParseCommandLine(int* argc, char** argv, Options* options) {
  try {
    *options = ParseOptions(argc, argv);
  } catch (const std::invalid_argument& e) {  // std::stoul on a malformed list, or a value
    fmt::print(stderr,
               "skinserve-bench: {} (--vertices= and --bones= take comma-separated counts, "
               "--methods= linear and dual-quaternion, --vertex-order= sorted or shuffled)\n",
               e.what());
    return false;
  } catch (const std::exception&) {  // std::stoul out of range
    fmt::print(stderr, "skinserve-bench: --vertices= and --bones= take comma-separated counts\n");
    return false;
  }
  const auto bad_bones = [](uint32_t b) { return b < 1 || b > kMaxInfluences; };
  if (std::count(options->vertices.begin(), options->vertices.end(), 0u) != 0 ||
      std::any_of(options->bones.begin(), options->bones.end(), bad_bones)) {
    fmt::print(stderr, "skinserve-bench: vertex counts must be >= 1 and bones 1..{}\n",
               kMaxInfluences);
    return false;
  }
  // Every speedup in the tables is against serial: measure it even when not asked for.
  if (options->paper_tables && !options->backends.empty() &&
      std::count(options->backends.begin(), options->backends.end(), "serial") == 0) {
    options->backends.push_back("serial");
  }
  return true;
}

// What the rows time: each measured backend under its id, and "opencl-global".
using Rows = std::vector<std::pair<std::string, Backend*>>;

// The backends asked for and available, in `backends`' order, into `measured` and `rows`;
// with --opencl-global-palette, `opencl` once more from a runtime that keeps the palette
// in global memory, after `opencl`'s row. False, the error printed, when a backend the
// options need is unavailable.
bool SelectRows(const Options& options, const std::vector<std::unique_ptr<Backend>>& backends,
                int threads, std::vector<std::string>* measured, Rows* rows) {
  if (!options.opencl_device.empty()) {
    for (const auto& backend : backends) {
      if (backend->info().id == "opencl" && !backend->info().available) {
        fmt::print(stderr, "skinserve-bench: {}\n", backend->info().unavailable_reason);
        return false;
      }
    }
  }
  for (const auto& backend : backends) {
    const BackendInfo& info = backend->info();
    const bool wanted = options.backends.empty() ||
                        std::count(options.backends.begin(), options.backends.end(), info.id);
    if (!wanted) continue;
    if (!info.available) {
      fmt::print(stderr, "skipping {}: {}\n", info.id, info.unavailable_reason);
      continue;
    }
    measured->push_back(info.id);
    rows->emplace_back(info.id, backend.get());
  }
  static std::vector<std::unique_ptr<Backend>> global_palette;  // lives through the run
  if (options.opencl_global_palette &&
      std::count(measured->begin(), measured->end(), "opencl") != 0) {
    global_palette = MakeOpenClBackends(
        OpenClRuntimeOptions{.threads = threads,
                             .device = options.opencl_device,
                             .local_palette = OpenClRuntimeOptions::LocalPalette::kOff,
                             .device_timing = options.opencl_device_timing});
    Backend& global = *global_palette.front();  // its `opencl`
    if (!global.info().available) {
      fmt::print(stderr, "skinserve-bench: --opencl-global-palette: {}\n",
                 global.info().unavailable_reason);
      return false;
    }
    for (std::size_t i = 0; i < rows->size(); ++i) {
      if ((*rows)[i].first == "opencl") {
        rows->insert(rows->begin() + static_cast<std::ptrdiff_t>(i) + 1,
                     {"opencl-global", &global});
        break;
      }
    }
  }
  return true;
}

const char* SkinRowPrefix(bool normals, bool tangents) {
  return tangents ? "BM_SkinTangents" : (normals ? "BM_SkinNormals" : "BM_Skin");
}

// BM_Skin[Normals|Tangents][DualQuaternion]/<backend>/<vertices>/<bones>: the float rows.
void RegisterSkinRows(const Options& options, const Rows& rows) {
  for (int outputs = 0; outputs < 3; ++outputs) {  // positions, + normals, + tangents
    const bool normals = outputs >= 1, tangents = outputs == 2;
    if (options.paper_tables && normals && !options.normals_in_tables) continue;
    if (tangents && !options.tangents) continue;
    for (uint32_t v : options.vertices) {
      for (uint32_t b : options.bones) {
        for (const auto& [id, backend] : rows) {
          if (tangents && !backend->info().tangents) continue;
          for (SkinningMethod method : options.methods) {
            if (!backend->info().Supports(method)) continue;
            const bool dqs = method == SkinningMethod::kDualQuaternion;
            const std::string name = fmt::format("{}{}/{}/{}/{}", SkinRowPrefix(normals, tangents),
                                                 dqs ? "DualQuaternion" : "", id, v, b);
            benchmark::RegisterBenchmark(name.c_str(), SkinBenchmark, backend, v, b, normals,
                                         method, RestEncoding::kFloat32, tangents)
                ->UseRealTime()
                ->Unit(benchmark::kMicrosecond);
          }
        }
      }
    }
  }
}

// --quantized: BM_Skin[Normals|Tangents]Quantized[Weights8]/<backend>/<vertices>/<bones>.
void RegisterQuantizedRows(const Options& options,
                           const std::vector<std::unique_ptr<Backend>>& backends,
                           const std::vector<std::string>& measured) {
  for (int outputs = 0; outputs < 3; ++outputs) {  // positions, + normals, + tangents
    if (!options.quantized) break;
    const bool normals = outputs >= 1, tangents = outputs == 2;
    if (tangents && !options.tangents) continue;
    for (uint32_t v : options.vertices) {
      for (uint32_t b : options.bones) {
        for (const auto& backend : backends) {
          if (std::count(measured.begin(), measured.end(), backend->info().id) == 0) continue;
          if (!backend->info().quantized_rest) continue;
          for (auto [kind, rest] :
               {std::pair{"Quantized", RestEncoding::kQuantized16},
                std::pair{"QuantizedWeights8", RestEncoding::kQuantized8Weights}}) {
            const std::string name = fmt::format("{}{}/{}/{}/{}", SkinRowPrefix(normals, tangents),
                                                 kind, backend->info().id, v, b);
            benchmark::RegisterBenchmark(name.c_str(), SkinBenchmark, backend.get(), v, b, normals,
                                         SkinningMethod::kLinear, rest, tangents)
                ->UseRealTime()
                ->Unit(benchmark::kMicrosecond);
          }
        }
      }
    }
  }
}

// One row's BM_Skin[Normals]HostEncoded<Encoding>/..., and BM_Skin[Normals]Encoded<Encoding>/...
// (with --streams=N, BM_SkinStreamsEncoded<Encoding>/...) when its backend writes the encoding
// itself.
void RegisterEncodedRow(const Options& options, const std::string& id, Backend* backend,
                        VertexEncoding encoding, bool normals, uint32_t v, uint32_t b) {
  const char* encoding_name = encoding == VertexEncoding::kFloat16 ? "Float16" : "Snorm16";
  auto* host = benchmark::RegisterBenchmark(
      fmt::format("{}HostEncoded{}/{}/{}/{}", normals ? "BM_SkinNormals" : "BM_Skin", encoding_name,
                  id, v, b)
          .c_str(),
      SkinHostEncodedBenchmark, backend, v, b, normals, encoding);
  host->UseRealTime()->Unit(benchmark::kMicrosecond);
  if (options.process_cpu_time) host->MeasureProcessCPUTime();
  if (!backend->info().WritesEncoding(encoding)) return;
  const std::string kind = std::string("Encoded") + encoding_name;
  const std::string name =
      fmt::format("{}{}/{}/{}/{}", normals ? "BM_SkinNormals" : "BM_Skin", kind, id, v, b);
  auto* direct = benchmark::RegisterBenchmark(name.c_str(), SkinEncodedBenchmark, backend, v, b,
                                              normals, encoding);
  direct->UseRealTime()->Unit(benchmark::kMicrosecond);
  if (options.process_cpu_time) direct->MeasureProcessCPUTime();
  if (options.streams > 1 && !normals) {
    benchmark::RegisterBenchmark(fmt::format("BM_SkinStreams{}/{}/{}/{}", kind, id, v, b).c_str(),
                                 SkinEncodedBenchmark, backend, v, b, false, encoding)
        ->Threads(options.streams)
        ->UseRealTime()
        ->Unit(benchmark::kMicrosecond);
  }
}

// --encoding=: the encoded rows of every row, encoding, output, vertex count and bones.
void RegisterEncodedRows(const Options& options, const Rows& rows) {
  for (VertexEncoding encoding : options.encodings) {
    for (bool normals : {false, true}) {
      for (uint32_t v : options.vertices) {
        for (uint32_t b : options.bones) {
          for (const auto& [id, backend] : rows) {
            RegisterEncodedRow(options, id, backend, encoding, normals, v, b);
          }
        }
      }
    }
  }
}

// --morph: BM_SkinMorph[Normals]/<backend>/<vertices>/<bones>/active:0 and active:4.
void RegisterMorphRows(const Options& options,
                       const std::vector<std::unique_ptr<Backend>>& backends,
                       const std::vector<std::string>& measured) {
  for (bool normals : {false, true}) {
    if (!options.morph) break;
    for (uint32_t v : options.vertices) {
      for (uint32_t b : options.bones) {
        for (const auto& backend : backends) {
          if (std::count(measured.begin(), measured.end(), backend->info().id) == 0) continue;
          if (!backend->info().morph_targets) continue;
          for (uint32_t active : {0u, 4u}) {
            const std::string name = fmt::format("{}/{}/{}/{}/active:{}",
                                                 normals ? "BM_SkinMorphNormals" : "BM_SkinMorph",
                                                 backend->info().id, v, b, active);
            benchmark::RegisterBenchmark(name.c_str(), SkinMorphBenchmark, backend.get(), v, b,
                                         normals, active)
                ->UseRealTime()
                ->Unit(benchmark::kMicrosecond);
          }
        }
      }
    }
  }
}

// --streams=N: BM_SkinStreams/<backend>/<vertices>/<bones> for the OpenCL rows.
void RegisterStreamRows(const Options& options, const Rows& rows) {
  for (uint32_t v : options.vertices) {
    for (uint32_t b : options.bones) {
      for (const auto& [id, backend] : rows) {
        if (id.rfind("opencl", 0) != 0) continue;
        const std::string name = fmt::format("BM_SkinStreams/{}/{}/{}", id, v, b);
        benchmark::RegisterBenchmark(name.c_str(), SkinBenchmark, backend, v, b, false,
                                     SkinningMethod::kLinear, RestEncoding::kFloat32, false)
            ->Threads(options.streams)
            ->UseRealTime()
            ->Unit(benchmark::kMicrosecond);
      }
    }
  }
}

// --tick=N: BM_SkinTick[Normals]/<backend>/<vertices>/<bones>/characters:N[/slots:K].
void RegisterTickRows(const Options& options, const Rows& rows) {
  if (options.tick == 0) return;
  for (bool normals : {false, true}) {
    for (uint32_t v : options.vertices) {
      for (uint32_t b : options.bones) {
        for (const auto& [id, backend] : rows) {
          for (auto [kind, rest] : {std::pair{"", RestEncoding::kFloat32},
                                    std::pair{"Quantized", RestEncoding::kQuantized16}}) {
            if (rest != RestEncoding::kFloat32 &&
                (!options.quantized || !backend->info().quantized_rest)) {
              continue;
            }
            const std::string slots =
                (options.tick_slots > 1 ? fmt::format("/slots:{}", options.tick_slots) : "") +
                (options.tick_gap_us > 0 ? fmt::format("/gap_us:{}", options.tick_gap_us) : "");
            const std::string name = fmt::format("{}{}/{}/{}/{}/characters:{}{}",
                                                 normals ? "BM_SkinTickNormals" : "BM_SkinTick",
                                                 kind, id, v, b, options.tick, slots);
            benchmark::RegisterBenchmark(name.c_str(), SkinTickBenchmark, backend, v, b, normals,
                                         options.tick, options.tick_slots, options.tick_gap_us,
                                         rest)
                ->UseRealTime()
                ->Unit(benchmark::kMillisecond);
          }
          if (backend->info().skins_frames_together && options.tick_slots == 1 &&
              options.tick_gap_us == 0) {
            const std::string name =
                fmt::format("{}/{}/{}/{}/characters:{}",
                            normals ? "BM_SkinTickTogetherNormals" : "BM_SkinTickTogether", id, v,
                            b, options.tick);
            benchmark::RegisterBenchmark(name.c_str(), SkinTickTogetherBenchmark, backend, v, b,
                                         normals, options.tick)
                ->UseRealTime()
                ->Unit(benchmark::kMillisecond);
          }
        }
      }
    }
  }
}

// The bounds: with OpenCL measured, the device's (PCIe each way, device copy, pinned
// copy-out) from a runtime of its own; then the pose rows and the memory bandwidth.
void RegisterBoundRows(bool opencl_measured, int threads, const std::string& opencl_device) {
  auto best = [](const std::vector<double>& values) {
    return *std::max_element(values.begin(), values.end());
  };
  static std::shared_ptr<OpenClRuntime> bound_runtime;
  if (opencl_measured) {
    auto runtime = OpenClRuntime::Create({.threads = threads, .device = opencl_device});
    if (runtime.ok()) {
      bound_runtime = *runtime;
      for (auto [name, bound] : {std::pair{"BM_PcieHostToDevice", DeviceBound::kHostToDevice},
                                 std::pair{"BM_PcieDeviceToHost", DeviceBound::kDeviceToHost},
                                 std::pair{"BM_DeviceMemoryCopy", DeviceBound::kDeviceCopy}}) {
        benchmark::RegisterBenchmark(name, DeviceBandwidth, bound_runtime.get(), bound)
            ->UseRealTime()
            ->Unit(benchmark::kMicrosecond)
            ->ComputeStatistics("max", best);
      }
      benchmark::RegisterBenchmark("BM_PinnedCopyOut", DeviceBandwidth, bound_runtime.get(),
                                   DeviceBound::kPinnedCopyOut)
          ->Arg(1)
          ->Arg(threads)
          ->UseRealTime()
          ->Unit(benchmark::kMicrosecond)
          ->ComputeStatistics("max", best);
    }
  }
  // The bound is what memory can do, and other processes only ever slow a run down: the
  // tables take the best repetition ("max" of bytes_per_second), not the median.
  RegisterPoseBenchmarks();  // the animation runtime's frame, beside the skinning rows
  benchmark::RegisterBenchmark("BM_MemoryBandwidth", MemoryBandwidth)
      ->UseRealTime()
      ->Unit(benchmark::kMillisecond)
      ->ComputeStatistics("max", best);
}

// Runs the registered rows: Google Benchmark's own reporter for --benchmark_format=json|csv,
// else the console with, after the runs, the paper tables (--paper-tables), the device
// bounds and the quantized rows' shares (--quantized).
int RunRows(const Options& options, int argc, char** argv, const Rows& rows) {
  // Our defaults go first, so that the same flags given on the command line win.
  std::string repetitions = "--benchmark_repetitions=3",
              aggregates = "--benchmark_report_aggregates_only=true";
  std::vector<char*> args = {argv[0]};
  if (options.paper_tables) {
    args.push_back(repetitions.data());
    args.push_back(aggregates.data());
  }
  args.insert(args.end(), argv + 1, argv + argc);
  // --benchmark_format=json|csv: Google Benchmark's own reporter, nothing else on stdout
  // (the paper tables belong to the console output only). The last occurrence wins, as in
  // Google Benchmark's own parsing (read before Initialize, which removes the flags it knows).
  std::string format = "console";
  for (std::size_t i = 1; i < args.size(); ++i) {
    constexpr std::string_view kFlag = "--benchmark_format=";
    if (std::string_view(args[i]).rfind(kFlag, 0) == 0) format = args[i] + kFlag.size();
  }
  int args_count = static_cast<int>(args.size());
  benchmark::Initialize(&args_count, args.data());
  if (benchmark::ReportUnrecognizedArguments(args_count, args.data())) return 1;
  if (format != "console") {
    if (options.paper_tables) {
      fmt::print(stderr,
                 "skinserve-bench: --paper-tables: the tables are printed with "
                 "--benchmark_format=console only\n");
    }
    benchmark::RunSpecifiedBenchmarks();  // the reporter --benchmark_format names
    benchmark::Shutdown();
    return 0;
  }
  PaperTablesReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  std::vector<std::string> tabled;  // the measured backends and "opencl-global"
  for (const auto& row : rows) tabled.push_back(row.first);
  if (options.paper_tables) reporter.PrintTables(tabled);
  reporter.PrintDeviceBounds();
  if (options.quantized) reporter.PrintQuantizedShares();
  benchmark::Shutdown();
  return 0;
}

}  // namespace
}  // namespace skinserve::bench

int main(int argc, char** argv) {
  using namespace skinserve;
  using namespace skinserve::bench;
  Options options;
  if (!ParseCommandLine(&argc, argv, &options)) return 2;
  Cache().set_sorted_by_joints(options.sorted_by_joints);
  const int threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  static std::vector<std::unique_ptr<Backend>> backends =
      CreateAllBackends(threads, options.opencl_device, options.opencl_device_timing);
  std::vector<std::string> measured;
  Rows rows;
  if (!SelectRows(options, backends, threads, &measured, &rows)) return 2;
  RegisterSkinRows(options, rows);
  if (options.device_output &&
      !RegisterDeviceOutputRows(Cache(), options.vertices, options.bones, threads,
                                options.opencl_device, options.opencl_device_timing,
                                options.tick)) {
    return 2;
  }
  RegisterQuantizedRows(options, backends, measured);
  RegisterEncodedRows(options, rows);
  RegisterMorphRows(options, backends, measured);
  const bool opencl_measured = std::count(measured.begin(), measured.end(), "opencl") +
                                   std::count(measured.begin(), measured.end(), "opencl-zerocopy") >
                               0;
  if (opencl_measured && options.streams > 1) RegisterStreamRows(options, rows);
  RegisterTickRows(options, rows);
  RegisterBoundRows(opencl_measured, threads, options.opencl_device);
  return RunRows(options, argc, argv, rows);
}
