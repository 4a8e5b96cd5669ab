// OpenClRuntime: the one platform, device, context and built program an engine shares
// between its OpenCL backends, created once at start-up, and its lanes: each lane an
// in-order compute queue, an in-order transfer queue, its own kernel objects and its own
// per-frame buffers, so frames on different lanes run on the device at the same time.
#pragma once

#include <CL/cl.h>

#include <algorithm>
#include <array>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "skinserve/engine/backend.h"
#include "skinserve/model/mesh.h"
#include "skinserve/model/skinning_method.h"
#include "skinserve/model/status.h"

namespace skinserve {

// "CL_INVALID_VALUE" for -30; "CL_UNKNOWN_ERROR" for codes OpenCL 1.2 does not define.
const char* ClErrorName(cl_int code);
// "clCreateBuffer(palette) failed: CL_INVALID_VALUE (-30)". Out-of-memory codes map to
// RESOURCE_EXHAUSTED, every other code to INTERNAL.
Status ClError(const char* call, cl_int code);

// Owns one cl_mem.
class ClBuffer {
 public:
  ClBuffer() = default;
  explicit ClBuffer(cl_mem mem) : mem_(mem) {}
  ClBuffer(ClBuffer&& other) noexcept : mem_(std::exchange(other.mem_, nullptr)) {}
  ClBuffer& operator=(ClBuffer&& other) noexcept {
    std::swap(mem_, other.mem_);
    return *this;
  }
  ClBuffer(const ClBuffer&) = delete;
  ClBuffer& operator=(const ClBuffer&) = delete;
  ~ClBuffer() {
    if (mem_ != nullptr) clReleaseMemObject(mem_);
  }
  cl_mem get() const { return mem_; }

 private:
  cl_mem mem_ = nullptr;
};

// Owns the events of one frame's commands.
class ClEvents {
 public:
  ClEvents() = default;
  ClEvents(const ClEvents&) = delete;
  ClEvents& operator=(const ClEvents&) = delete;
  ~ClEvents() {
    for (cl_event event : events_) {
      if (event != nullptr) clReleaseEvent(event);
    }
  }
  // Where the next enqueue writes its event; it is owned from then on.
  cl_event* Next() { return &events_.emplace_back(nullptr); }
  const std::vector<cl_event>& all() const { return events_; }

 private:
  std::vector<cl_event> events_;
};

// Device time of the commands in `events` (CL_PROFILING_COMMAND_END - _START, summed).
Result<int64_t> ProfiledNs(const std::vector<cl_event>& events);

// A finished frame's kernel and transfer time into *timing (nothing when it is null).
// Nothing, too, when the lane's queues are not profiled (`profiled`: the runtime's
// device_timing()).
Status RecordDeviceTiming(const ClEvents& kernels, const ClEvents& transfers, bool profiled,
                          DeviceTiming* timing);

// The device-side arrays of one frame and its method. `normals` and `out_normals` are null
// when the frame skips normals, `tangents` and `out_tangents` (4 floats per vertex) when it
// skips tangents (a frame with tangents has normals too). `palette` holds 12 floats per joint (the
// 3x4 matrices) for linear blending, 8 (the frame's DualQuaternionPalette) for dual quaternions.
struct SkinKernelArgs {
  SkinningMethod method = SkinningMethod::kLinear;
  cl_mem palette = nullptr;
  cl_mem joints = nullptr;
  cl_mem weights = nullptr;
  cl_mem positions = nullptr;
  cl_mem out_positions = nullptr;
  cl_mem normals = nullptr;
  cl_mem out_normals = nullptr;
  cl_mem tangents = nullptr;
  cl_mem out_tangents = nullptr;
};

// The device-side arrays of one frame's morph (kernels/morph_targets.cl): the mesh's rest
// arrays and targets (on the device once per mesh, OpenClMorphTargets), the frame's active
// weights (`weights`: `weight_count` MorphWeight entries) and where the morphed rest arrays
// go. The normals' three are all set (the frame's normals are morphed) or all null; so are
// the tangents' (4 floats per vertex, 3 per delta: their w is never morphed).
struct MorphKernelArgs {
  cl_mem positions = nullptr;
  cl_mem offsets = nullptr;
  cl_mem indices = nullptr;
  cl_mem position_deltas = nullptr;
  cl_mem weights = nullptr;
  cl_uint weight_count = 0;
  cl_mem morphed_positions = nullptr;
  cl_mem normals = nullptr;
  cl_mem normal_deltas = nullptr;
  cl_mem morphed_normals = nullptr;
  cl_mem tangents = nullptr;
  cl_mem tangent_deltas = nullptr;
  cl_mem morphed_tangents = nullptr;
};

// Page-locked host memory (CL_MEM_ALLOC_HOST_PTR, mapped for the buffer's lifetime), for
// transfers the DMA engine does at the link's speed without the driver's own staging.
struct PinnedBuffer {
  ClBuffer buffer;
  void* host = nullptr;
  std::size_t bytes = 0;
};

class OpenClRuntime;
class OpenClQuantizedKernels;  // opencl_quantized.h

// One lane: queues, kernels and the per-frame buffers a backend keeps on it. Used by one
// frame at a time (OpenClRuntime::Lease).
struct OpenClLane {
  cl_command_queue compute = nullptr;   // kernels (and, on a CPU device, every command)
  cl_command_queue transfer = nullptr;  // read-backs, so they overlap the next kernel
  // [palette in local memory][dual quaternion][outputs][influences - 1], outputs
  // (SkinOutputs) 0 positions, 1 with normals, 2 with normals and tangents: skin_b*,
  // skin_normals_b*, skin_tangents_b* and their dqs_* twins, then (only with
  // OpenClRuntime::local_palette()) their *_local_* variants, which stage the palette in
  // work-group local memory first.
  std::array<std::array<std::array<std::array<cl_kernel, kMaxInfluences>, 3>, 2>, 2> kernels = {};
  // [with normals][with tangents]: morph_positions, morph_positions_tangents,
  // morph_positions_normals, morph_positions_normals_tangents.
  std::array<std::array<cl_kernel, 2>, 2> morph_kernels = {};
  // The copy backend's per-frame buffers, grown to the largest frame this lane has run.
  ClBuffer palette, out_positions, out_normals, out_tangents;
  std::size_t palette_bytes = 0, positions_bytes = 0, normals_bytes = 0, tangents_bytes = 0;
  // Both backends' morph buffers: the frame's morphed rest arrays (and, for the copy
  // backend, its active weights), grown like the above; untouched by frames without morphs.
  ClBuffer morph_weights, morphed_positions, morphed_normals, morphed_tangents;
  std::size_t morph_weights_bytes = 0, morphed_positions_bytes = 0, morphed_normals_bytes = 0,
              morphed_tangents_bytes = 0;
  PinnedBuffer pinned_palette, pinned_positions, pinned_normals, pinned_tangents;
  // A batch's palettes (OpenClCopyBackend::SkinFrames), one slot a frame, and its host
  // frames' read-backs, one after another.
  PinnedBuffer pinned_batch_palettes, pinned_batch_outputs;
  // Tick launches (kernels/tick_skinning.cl, opencl_tick_launch.h): [local][outputs][B - 1]
  // tick_b*, tick_normals_b*, tick_tangents_b* (and *_local_* with the local palette); a
  // batch's palettes and character tables on the device, and its host outputs before
  // they are read back; grown like the buffers above.
  std::array<std::array<std::array<cl_kernel, kMaxInfluences>, 3>, 2> tick_kernels = {};
  ClBuffer tick_palettes, tick_tables, tick_outputs;
  PinnedBuffer pinned_tick_palettes;
  std::size_t tick_palettes_bytes = 0, tick_tables_bytes = 0, tick_outputs_bytes = 0;
};

// One tick launch (OpenClRuntime::EnqueueTick): `characters` rows of `table` from
// `first_row` on (kTickFields
// uints each, kernels/tick_skinning.cl) over meshes in `arena` (one chunk of the mesh
// arena), palettes in `palettes`, outputs into `out`; every character with `influences`
// influences and `outputs` (0 positions, 1 with normals, 2 with normals and tangents).
// `local`: the *_local_* kernels, staging up to `staged_bytes` of palette.
struct TickLaunch {
  cl_mem arena = nullptr, table = nullptr, palettes = nullptr, out = nullptr;
  uint32_t first_row = 0, characters = 0, influences = 0, most_vertices = 0;
  int outputs = 0;
  bool local = false;
  std::size_t staged_bytes = 0;
};
// A row of a tick launch's table: kTickFields uints (TICK_FIELDS of the kernels).
inline constexpr std::size_t kTickFields = 11;

struct OpenClRuntimeOptions {
  // Compute threads of the engine: PoCL's worker count, and the host threads the copy
  // backend's frames share for copying results out of pinned memory (Lease::copy_threads).
  int threads = 1;
  // "" (the first CPU device, else the first device), "cpu", "gpu", or a case-insensitive
  // substring of a platform's or a device's name.
  std::string device;
  // Lanes: 0 chooses (4 with staging; else 1: on a CPU device one frame already occupies
  // every PoCL thread).
  int lanes = 0;
  // Pinned staging and chunked transfers even on a device that shares host memory (for
  // tests of that path on PoCL); devices with memory of their own always use them.
  bool force_staging = false;
  // With staging, a frame of V vertices runs in up to max_chunks chunks of at least
  // min_chunk_vertices (0: SKINSERVE_OPENCL_CHUNKS if set, else kDefaultChunks). Each
  // chunk costs a wait on its event and a start of the copy-out's threads (tens of us on
  // NVIDIA's driver): on the H100, 1.6M vertices ran fastest in 2 chunks, 400k in 1 (see
  // docs/backends/opencl.md, "Chunks").
  int max_chunks = 0;
  uint32_t min_chunk_vertices = 512 * 1024;
  // The GPU's kernel shape (SKIN_COALESCED 1: neighbouring work-items take neighbouring
  // vertices) even on a CPU device, so that tests run it on PoCL; a GPU always has it.
  bool force_coalesced = false;
  // On the coalesced path (a GPU, or force_coalesced), stage a frame's palette in
  // work-group local memory (SKIN_LOCAL_PALETTE 1, the *_local_* kernels) whenever it
  // fits: kAuto; kOff never (the benchmark's comparison rows). The CPU path (not
  // coalesced) never stages: there local memory is ordinary memory.
  enum class LocalPalette { kAuto, kOff };
  LocalPalette local_palette = LocalPalette::kAuto;
  // The most palette bytes a work-group stages: the device's CL_DEVICE_LOCAL_MEM_SIZE less
  // what the kernels use themselves, and at most this when it is not 0 (tests set less,
  // to take the global kernels with larger palettes). A frame whose palette (12 floats per joint
  // linear, 8 dual quaternion) is larger runs the global kernels.
  std::size_t local_palette_max_bytes = 0;
  // Tiles of 256 vertices a work-group skins after one copy of the palette (0:
  // SKINSERVE_OPENCL_LOCAL_TILES if set, else kDefaultLocalTiles).
  int local_tiles = 0;
  // Queues with CL_QUEUE_PROFILING_ENABLE, so that each frame reports its kernel and
  // transfer time (DeviceTiming, ServerTiming.device_*_ns). Off, those stay 0: on the H200
  // profiling made a frame's palette write, kernel and wait cost 28-32 us instead of 13-16
  // (docs/results/2026-11-29-gpu-frame-floor-h200).
  bool device_timing = false;
  // Each chunk of the copy backend's device mesh arena (opencl_mesh_arena.h); 0:
  // OpenClMeshArena::kDefaultChunkBytes. Tests set less, to fill chunks.
  std::size_t mesh_arena_bytes = 0;
  // Tick launches (opencl_tick_launch.h) for the frames that can take them; false (or
  // SKINSERVE_OPENCL_TICK_LAUNCHES=0 in the environment) runs every frame of a batch on
  // its own, for the benchmarks' comparison.
  bool tick_launches = true;
};

class OpenClRuntime {
 public:
  // Picks the device, sets PoCL's thread count to `threads` (unless POCL_MAX_PTHREAD_COUNT
  // is set), builds the program and runs every kernel once on every lane so that the
  // first real frame compiles nothing. FAILED_PRECONDITION (no platform, no device, no
  // device matching the choice - with the list of what there is - or the build log) or
  // the failing call's error.
  static Result<std::shared_ptr<OpenClRuntime>> Create(const OpenClRuntimeOptions& options);
  ~OpenClRuntime();
  OpenClRuntime(const OpenClRuntime&) = delete;
  OpenClRuntime& operator=(const OpenClRuntime&) = delete;

  // A lane held by one frame; returned to the pool when destroyed. Blocks while every
  // lane is busy.
  class Lease {
   public:
    Lease(OpenClRuntime* runtime, OpenClLane* lane, int busy)
        : runtime_(runtime), lane_(lane), busy_(busy) {}
    Lease(const Lease&) = delete;
    Lease& operator=(const Lease&) = delete;
    ~Lease() { runtime_->Release(lane_); }
    OpenClLane& operator*() const { return *lane_; }
    OpenClLane* operator->() const { return lane_; }
    // Host threads this frame may use to copy its results out of pinned memory: the
    // engine's threads shared among the lanes busy when it was acquired (this one too).
    int copy_threads() const { return std::max(1, runtime_->threads_ / busy_); }

   private:
    OpenClRuntime* runtime_;
    OpenClLane* lane_;
    int busy_;
  };
  Lease AcquireLane();

  // Sets the arguments of `lane`'s kernel for args.method and `mesh`'s influence count
  // (with normals when args.out_normals is set, and tangents when args.out_tangents is) and
  // enqueues it on the lane's compute queue over
  // vertices [first, end) (first a multiple of kChunkAlignment). `event`: null or where to put the
  // kernel's event.
  Status EnqueueSkin(OpenClLane& lane, const Mesh& mesh, const SkinKernelArgs& args, uint32_t first,
                     uint32_t end, cl_event* event);
  // Enqueues `lane`'s morph kernel (with normals when args.morphed_normals is set, tangents
  // when args.morphed_tangents is) over all
  // `vertex_count` vertices on the lane's compute queue: the skinning kernels enqueued after
  // it on that queue read its output. `event`: null or where to put the kernel's event.
  Status EnqueueMorph(OpenClLane& lane, uint32_t vertex_count, const MorphKernelArgs& args,
                      cl_event* event);
  // Sets the arguments of `lane`'s tick kernel for `launch` and enqueues it on the lane's
  // compute queue. `event`: null or where to put the kernel's event.
  Status EnqueueTick(OpenClLane& lane, const TickLaunch& launch, cl_event* event);
  // A buffer: device memory (host == nullptr), a copy of `host`, or `host` used in place
  // (CL_MEM_USE_HOST_PTR). `what` names the buffer in errors.
  Result<ClBuffer> CreateBuffer(const char* what, cl_mem_flags flags, std::size_t bytes,
                                const void* host);
  // Makes `buffer` (device memory, `flags`) hold at least `bytes`, `capacity` its size.
  Status GrowBuffer(const char* what, cl_mem_flags flags, std::size_t bytes, ClBuffer* buffer,
                    std::size_t* capacity);
  // Makes `pinned` page-locked host memory of at least `bytes`, mapped on `queue` for
  // reading and writing (unmapping the old one).
  Status GrowPinned(cl_command_queue queue, const char* what, std::size_t bytes,
                    PinnedBuffer* pinned);

  // Vertex ranges of a chunked frame start at multiples of this (one work-group's).
  static constexpr uint32_t kChunkAlignment = 256;

  cl_context context() const { return context_; }
  cl_device_id device() const { return device_; }
  const std::string& device_name() const { return device_name_; }
  // The platform's version, e.g. "OpenCL 3.0 PoCL 3.1+debian".
  const std::string& platform_version() const { return platform_version_; }
  // Compute units: PoCL's worker threads on its CPU device, SMs on an NVIDIA GPU.
  int compute_units() const { return compute_units_; }
  int vector_width() const { return vector_width_; }
  // CL_DEVICE_MEM_BASE_ADDR_ALIGN in bytes: where a sub-buffer may start.
  uint64_t base_address_alignment() const { return base_address_alignment_; }
  bool is_cpu() const { return is_cpu_; }
  // Whether frames go through pinned staging in chunks (a device with memory of its own,
  // or forced): else the device reads and writes host memory directly.
  bool staging() const { return staging_; }
  // Whether the lanes' queues are profiled (OpenClRuntimeOptions::device_timing).
  bool device_timing() const { return device_timing_; }
  // OpenClRuntimeOptions::mesh_arena_bytes as given.
  std::size_t mesh_arena_bytes() const { return mesh_arena_bytes_; }
  bool tick_launches() const { return tick_launches_; }
  int lane_count() const { return static_cast<int>(lanes_.size()); }
  int max_chunks() const { return max_chunks_; }
  uint32_t min_chunk_vertices() const { return min_chunk_vertices_; }
  static constexpr int kDefaultChunks = 2;
  // Whether the kernels take the GPU's coalesced vertex order (SKIN_COALESCED 1).
  bool coalesced() const { return coalesced_; }
  // Whether the *_local_* kernels are built, and the most palette bytes they stage (0: not
  // built). UsesLocalPalette: whether a frame of `mesh` with `method` runs them.
  bool local_palette() const { return local_palette_bytes_ > 0; }
  std::size_t local_palette_bytes() const { return local_palette_bytes_; }
  bool UsesLocalPalette(const Mesh& mesh, SkinningMethod method) const;
  int local_tiles() const { return local_tiles_; }
  static constexpr int kDefaultLocalTiles = 1;
  // The qskin_* kernels of meshes with a quantized rest stream; EnqueueSkin takes them for
  // such a mesh.
  OpenClQuantizedKernels& quantized_kernels() { return *quantized_; }

 private:
  OpenClRuntime() = default;
  // Create's steps, in order.
  Status ReadDeviceShape(const OpenClRuntimeOptions& options);
  Status BuildPrograms();
  Status Build(const std::string& options);
  void SetChunks(const OpenClRuntimeOptions& options);
  Status FitLocalPalette(const OpenClRuntimeOptions& options);
  Status CreateLanes(int count);
  // Sets the kernel's arguments and enqueues it (the *_local_* kernel when `local`).
  Status EnqueueSkinKernel(OpenClLane& lane, const Mesh& mesh, const SkinKernelArgs& args,
                           uint32_t first, uint32_t end, bool local, cl_event* event);
  // Runs every kernel once per lane on a one-vertex mesh (PoCL compiles a kernel for its
  // work-group size at its first launch, which would otherwise land in the first frames).
  struct WarmUpBuffers;
  Status Warm();
  Result<std::unique_ptr<WarmUpBuffers>> CreateWarmUpBuffers();
  Status WarmSkinKernels(OpenClLane& lane, const WarmUpBuffers& buffers);
  Status WarmMorphKernels(OpenClLane& lane, const WarmUpBuffers& buffers);
  Status WarmTickKernels(OpenClLane& lane, const WarmUpBuffers& buffers);
  void Release(OpenClLane* lane);

  cl_device_id device_ = nullptr;
  cl_context context_ = nullptr;
  cl_program program_ = nullptr;
  std::vector<std::unique_ptr<OpenClLane>> lanes_;
  std::mutex lanes_mutex_;
  std::condition_variable lane_freed_;
  std::vector<OpenClLane*> free_lanes_;
  std::string device_name_;
  std::string platform_version_;
  int compute_units_ = 1;
  uint64_t base_address_alignment_ = 4096;
  int vector_width_ = 1;
  bool is_cpu_ = true;
  bool staging_ = false;
  bool coalesced_ = false;
  bool device_timing_ = false;
  std::size_t mesh_arena_bytes_ = 0;
  bool tick_launches_ = true;
  std::size_t local_palette_bytes_ = 0;
  int local_tiles_ = kDefaultLocalTiles;
  int threads_ = 1;
  int max_chunks_ = kDefaultChunks;
  uint32_t min_chunk_vertices_ = 1;
  std::unique_ptr<OpenClQuantizedKernels> quantized_;
};

}  // namespace skinserve
