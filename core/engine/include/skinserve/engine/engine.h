// Engine: the backends by id, the mesh store and the compute threads. Usable in-process;
// the server is a thin translation of wire messages onto it.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "skinserve/animation/animation_store.h"
#include "skinserve/engine/backend.h"
#include "skinserve/model/mesh.h"
#include "skinserve/model/status.h"

namespace skinserve {

struct EngineOptions {
  int compute_threads = 0;           // 0: one per core
  std::size_t queue_capacity = 256;  // frames waiting for a compute thread
  uint32_t max_instances = 64;       // crowd batches: instances per request
  // A parallel backend's frame is split across threads only when nothing else waits and
  // each thread gets at least this many vertices (waking a team costs ~10-50 us; a
  // 25k-vertex, 2-bone frame takes ~50 us on one thread).
  uint64_t split_min_vertices = 50'000;
  uint64_t mesh_budget_bytes = 4ull << 30;  // LRU eviction beyond this
  // Skeletons and compact clips (animations()): uploads beyond it are refused.
  uint64_t clip_budget_bytes = 64ull << 20;
  MeshOptions mesh;                           // limits and weight policy on ingest
  std::vector<std::string> enabled_backends;  // ids; empty: all
  // The OpenCL backends' device: "" (the first CPU device, else the first device), "cpu",
  // "gpu", or part of a platform or device name. A choice that finds no device fails
  // Engine::Create (with the devices there are); "" leaves OpenCL unavailable instead.
  std::string opencl_device;
  // OpenCL frames report their kernel and transfer time (FrameTiming::device_*_ns): the
  // queues are profiled, which on the H200 roughly doubled a small frame's fixed GPU cost.
  bool opencl_device_timing = false;
  // Runs on the compute thread after a backend prepared a mesh (its first frame there),
  // before that frame is skinned. Preparing may compile OpenCL kernels, and the compiler
  // (PoCL's LLVM) may replace process-wide signal handlers: the server puts its SIGBUS
  // guard back here, once per prepared mesh instead of before every frame.
  std::function<void()> after_prepare;
};

struct MeshInfo {
  std::string id;
  uint32_t vertex_count = 0;
  uint32_t influences = 0;
  uint32_t joint_count = 0;
  bool has_normals = false;
  bool has_tangents = false;
  uint64_t bytes = 0;
  uint32_t normalized_vertices = 0;
  bool already_stored = false;  // the same content was stored before (dedupe)
  uint32_t morph_target_count = 0;
  RestEncoding rest_encoding = RestEncoding::kFloat32;
};

// Server-side time of one frame, for the wire's timing breakdown.
struct FrameTiming {
  int64_t queued_ns = 0;  // from Submit until a compute thread took it
  // From the first instance's start to the last instance's end: SkinJob::FillInputs (if
  // asked for), the backend's Skin calls and, in between, each instance's
  // SkinJob::OnInstanceSkinned.
  int64_t compute_ns = 0;
  // Of compute_ns, device time from profiling events (OpenCL backends; else 0):
  int64_t device_transfer_ns = 0;  // host<->device transfers, summed
  int64_t device_kernel_ns = 0;    // kernels, summed
};

// One frame to skin: one instance of a mesh, or a crowd of `instances` instances (K), each
// with its own palette, skinned side by side. Inputs and outputs are caller-owned and
// must stay valid until the frame is done; instance i's arrays follow instance i-1's.
struct SkinRequest {
  std::string mesh_id;
  std::string backend;
  std::span<const float> palette;  // 12 * joint_count * K floats
  uint32_t instances = 1;          // K; 0 means 1; at most EngineOptions::max_instances
  std::span<float> positions;      // 3 * vertex_count * K
  std::span<float> normals;        // empty: no normals; else 3 * vertex_count * K
  std::span<float> tangents;       // empty: no tangents; else 4 * vertex_count * K (needs normals)
  SkinningMethod method = SkinningMethod::kLinear;  // the backend must list it
  // The frame's active morph targets (sparse, morph_targets.h), the same for every instance
  // of a crowd; the backend must support morph targets (BackendInfo::morph_targets) when a
  // weight is non-zero.
  std::span<const MorphWeight> morph_weights;
  // Crowds with weights per instance: instance k takes instance_morph_weights[k] (checked
  // as morph_weights). Set: exactly `instances` entries, and morph_weights empty.
  std::span<const std::span<const MorphWeight>> instance_morph_weights;
  // Jobs only (Engine::Submit(SkinJob*)): skin each instance into scratch memory of the
  // compute thread that runs it and hand it to SkinJob::OnInstanceSkinned, which must use
  // it up (e.g. encode it) before returning; positions and normals then stay empty. Keeps a
  // crowd's float results in that core's cache instead of streaming a frame-sized buffer
  // through memory. At most kMaxScratchFloatsPerInstance floats per instance (positions
  // and normals together), so each compute thread keeps at most that much.
  bool skin_into_scratch = false;
  bool scratch_normals = false;  // with skin_into_scratch: skin normals too
  // Jobs only: the palette's values are written by the job (SkinJob::FillInputs) on the
  // compute thread that skins the frame, just before the backend reads them, instead of
  // before Submit (a server turning a pose into a palette spreads that work over the
  // compute threads with the skinning). `palette` spans where they will be: one instance's
  // 12 * joint_count floats, whose size Submit checks; their values are checked after
  // FillInputs, on that thread.
  bool fill_inputs_on_run = false;
  // Set (encoding not float32): the backend writes each instance encoded here instead of
  // into positions/normals/tangents, which stay empty (backend.h's EncodedOutput; the
  // backend's BackendInfo::encoded_outputs must list the encoding). Instance i's bytes
  // follow instance i-1's; `bounds` points at `instances` boxes (snorm16); `box_scratch`,
  // if given, holds 3 * vertex_count floats per instance, likewise one after another.
  EncodedOutput encoded;
  // Set: every instance is written as float32 into device memory the frame's backend
  // imported (Engine::ImportDeviceMemory), at the offsets DeviceOutput states; positions,
  // normals, tangents and encoded stay empty.
  DeviceOutput device;
};

inline constexpr std::size_t kMaxScratchFloatsPerInstance = std::size_t{1} << 20;  // 4 MiB
// The scratch floats one instance takes: positions, then normals from the next cache line.
constexpr std::size_t ScratchFloatsPerInstance(uint32_t vertex_count, bool normals) {
  const std::size_t outputs = 3ull * vertex_count;
  constexpr std::size_t kFloatsPerLine = 16;
  return normals ? (outputs + kFloatsPerLine - 1) / kFloatsPerLine * kFloatsPerLine + outputs
                 : outputs;
}
using SkinDone = std::function<void(Status, FrameTiming)>;

// What Engine::Plan found for a frame: its mesh's shape. While a job holds a plan its mesh
// stays stored (pinned), until the frame is done or the plan is dropped.
struct FramePlan {
  bool planned = false;
  uint32_t instances = 1;  // the batch Plan checked (SkinRequest::instances, 0 read as 1)
  uint32_t vertex_count = 0;
  uint32_t joint_count = 0;
  bool has_normals = false;
  bool has_tangents = false;
  uint32_t morph_target_count = 0;
  // Bit e set: the backend writes VertexEncoding e itself (BackendInfo::encoded_outputs).
  uint32_t backend_encodings = 0;
  // The backend keeps snorm16 positions as floats in EncodedOutput::box_scratch
  // (BackendInfo::encoded_box_scratch).
  bool backend_box_scratch = false;
  bool BackendWrites(VertexEncoding e) const {
    return (backend_encodings >> static_cast<unsigned>(e)) & 1u;
  }
};
// FramePlan::backend_encodings of `info`.
inline uint32_t EncodingMask(const BackendInfo& info) {
  uint32_t mask = 0;
  for (VertexEncoding e : info.encoded_outputs) mask |= 1u << static_cast<unsigned>(e);
  return mask;
}

// A plan its caller keeps across frames (a stream's: server/frames/stream_plan.h): what
// Engine::Plan checked and found for one mesh, backend, method and batch size, with the
// mesh held weakly, so that a quiet stream never holds up deleting or evicting it.
// Engine::Keep fills it from a planned job; Engine::Reuse hands it to the next job with no
// lookup and no lock.
class KeptPlan {
 public:
  bool kept() const { return plan_.planned; }
  const FramePlan& plan() const { return plan_; }
  void Reset() {
    mesh_.reset();
    plan_ = {};
  }

 private:
  friend class Engine;
  std::weak_ptr<void> mesh_;  // the mesh store's entry
  FramePlan plan_;
  std::size_t backend_index_ = 0;
};

// A frame the caller owns and reuses frame after frame, so that the steady-state path
// allocates nothing: fill `request`, Engine::Submit(job); OnInstanceSkinned runs once per
// instance skinned without error, and OnSkinned once, after every instance. Resubmit only
// after OnSkinned has run.
class SkinJob {
 public:
  SkinJob() = default;
  SkinJob(const SkinJob&) = delete;
  SkinJob& operator=(const SkinJob&) = delete;
  virtual ~SkinJob() = default;

  SkinRequest request;
  // Set by Engine::Plan (and by Submit for a job not planned before).
  const FramePlan& plan() const { return plan_; }

 protected:
  // Lets go of a plan whose frame will not be submitted (the mesh is no longer pinned).
  void DropPlan() {
    lease_.reset();
    plan_ = {};
  }
  // Runs on the compute thread that skinned `instance`, right after it, while its output is
  // still in that core's cache (e.g. to encode it); other instances' calls may run at the
  // same time on other threads. `positions` and `normals` (empty without normals) are the
  // instance's output: its part of the request's arrays, or with skin_into_scratch the
  // thread's scratch, valid until this returns. Non-OK fails the frame as a failed instance
  // would.
  virtual Status OnInstanceSkinned(uint32_t /*instance*/, std::span<const float> /*positions*/,
                                   std::span<const float> /*normals*/) {
    return Status::Ok();
  }
  // With request.fill_inputs_on_run: writes the frame's palette into the floats
  // request.palette spans. Runs once per frame, on the thread that then skins it (a compute
  // thread, or Engine::Run's caller when it runs the frame inline), before the backend
  // reads the palette; its time counts in the frame's compute_ns. Non-OK fails the frame,
  // which is then not skinned.
  virtual Status FillInputs() {
    return Internal("request.fill_inputs_on_run is set but the job does not fill its inputs");
  }
  // Runs once, on a compute thread, after every instance (and its OnInstanceSkinned).
  virtual void OnSkinned(Status status, const FrameTiming& timing) = 0;

 private:
  friend class Engine;
  // The engine's bookkeeping for the frame in flight.
  std::shared_ptr<void> lease_;  // pins the mesh
  FramePlan plan_;
  void* engine_ = nullptr;
  std::size_t backend_index_ = 0;
  uint32_t vertex_count_ = 0;
  int64_t submitted_ns_ = 0;
  std::atomic<int64_t> started_ns_{0};
  std::atomic<uint32_t> remaining_{0};
  std::atomic<int64_t> device_transfer_ns_{0};  // OpenCL instances' device time, summed
  std::atomic<int64_t> device_kernel_ns_{0};
  std::mutex status_mutex_;
  Status status_;  // the first failure among the instances
};

// Jobs submitted together (Engine::SubmitGroup): the characters of a tick. The caller
// keeps the group and its jobs alive, unchanged, until every accepted job's OnSkinned ran.
class SkinGroup {
 public:
  std::vector<SkinJob*> jobs;

 private:
  friend class Engine;
  std::vector<SkinJob*> queued_;  // the accepted jobs of the group's one task
  // The accepted jobs whose frames go to their backend together (output in device memory,
  // or a backend with BackendInfo::skins_frames_together): their own task, in
  // together_parts_ contiguous chunks, each chunk's frames handed over at once
  // (Backend::SkinFrames).
  std::vector<SkinJob*> together_;
  uint32_t together_parts_ = 0;
};

struct BackendStats {
  std::string id;
  uint64_t frames = 0;
  uint64_t vertices = 0;
  uint64_t errors = 0;
  int64_t compute_ns_total = 0;
};

struct EngineStats {
  std::vector<BackendStats> backends;
  std::size_t queue_depth = 0;
  std::size_t queue_capacity = 0;
  int compute_threads = 0;
  std::size_t meshes = 0;
  uint64_t mesh_bytes = 0;
  uint64_t mesh_budget_bytes = 0;
  uint64_t evictions = 0;
  uint64_t rejected_queue_full = 0;
  int peak_busy_threads = 0;   // most compute threads ever skinning at once
  uint64_t inline_frames = 0;  // frames Engine::Run skinned on its caller's thread
  uint64_t plans_built = 0;    // Engine::Plan calls that found their mesh and backend
  uint64_t plans_reused = 0;   // Engine::Reuse calls that could reuse their kept plan
};

class Engine {
 public:
  // Builds every enabled backend (the OpenCL program included) before returning, so a
  // server that holds an Engine is ready to serve.
  static Result<std::unique_ptr<Engine>> Create(const EngineOptions& options);
  ~Engine();  // Shutdown(), then joins the compute threads

  const EngineOptions& options() const;
  // Enabled backends in a stable order, available or not (with the reason).
  std::vector<BackendInfo> Backends() const;

  // Checks an upload's declared shape against the limits and the mesh budget before any
  // array is received or allocated (INVALID_ARGUMENT or RESOURCE_EXHAUSTED); morph
  // targets' sizes count towards the budget.
  Status CheckMeshShape(uint64_t vertex_count, uint64_t influences, uint64_t joint_count,
                        bool has_normals, std::span<const uint32_t> morph_target_sizes = {},
                        bool morph_normals = false,
                        RestEncoding rest_encoding = RestEncoding::kFloat32,
                        bool has_tangents = false, bool morph_tangents = false) const;
  // Validates and stores a mesh (dedupe by content id; LRU eviction beyond the budget).
  // `weight_policy` overrides the engine's (options().mesh) for this mesh; `rest_encoding`
  // other than kFloat32 also builds a quantized rest stream (quantized_rest.h), which the
  // `simd` loops read; every other backend skins the float arrays it decodes to.
  Result<MeshInfo> AddMesh(const MeshArrays& arrays,
                           std::optional<WeightPolicy> weight_policy = std::nullopt,
                           RestEncoding rest_encoding = RestEncoding::kFloat32);
  Result<MeshInfo> GetMesh(const std::string& id) const;
  // The same into `info`, reusing its strings (no allocation once they have grown).
  Status GetMesh(const std::string& id, MeshInfo* info) const;
  // Whether a batch of `instances` (0 means 1) of a mesh of `vertex_count` vertices is
  // within the limits (max_instances; instances * vertex_count <= max_vertices), so a
  // caller can check before sizing its buffers. INVALID_ARGUMENT naming the limit.
  Status CheckBatch(uint32_t vertex_count, uint32_t instances) const;
  bool DeleteMesh(const std::string& id);

  // Checks what a frame needs known before its buffers are sized, from job->request's
  // mesh_id, backend, method and instances: the backend (unknown or unavailable, or
  // without the method: INVALID_ARGUMENT), the mesh (NOT_FOUND: upload it again), the
  // batch (instances, instances x vertices: INVALID_ARGUMENT); pins the mesh and fills
  // job->plan(). A caller that plans looks the mesh up once: Submit uses the plan.
  // Allocates nothing.
  Status Plan(SkinJob* job);
  // Keeps the plan of `job` (planned: Plan returned OK, not yet submitted) in `kept`.
  void Keep(const SkinJob& job, KeptPlan* kept) const;
  // Plans `job` from `kept` as Plan would have, without looking anything up: pins the
  // kept mesh unless it was deleted or evicted since (then false, the job unplanned, and
  // Plan(job) finds out afresh). The caller sees to it that job->request's mesh_id,
  // backend, method and instances are those `kept` was planned with (Submit refuses a
  // batch size that differs).
  bool Reuse(const KeptPlan& kept, SkinJob* job);
  // Plans the job unless it was planned, checks the rest of the request (palette and
  // output sizes, for dual-quaternion a joint that is not rigid, morph weights:
  // INVALID_ARGUMENT naming the instance or the field; morph weights for a backend without
  // morph targets: FAILED_PRECONDITION naming it; full queue: RESOURCE_EXHAUSTED; shut down:
  // UNAVAILABLE) and queues it. On OK, OnSkinned is called exactly once, on a compute thread; on an
  // error, never, and the plan is dropped. Allocates nothing.
  Status Submit(SkinJob* job);
  // Submit, or when handing the frame to a compute thread buys no parallelism
  // (ComputePool::TryRunInline: a free thread, nothing queued, one instance too small to
  // split) skins it on the calling thread: OnSkinned then runs before Run returns, so the
  // caller must hold no lock that OnSkinned takes. The server's reactors call this: a small
  // frame costs no thread switch to a compute thread and back.
  Status Run(SkinJob* job);
  // Submits group->jobs together. Each is planned and checked as Submit does, and
  // statuses[i] (jobs.size() entries) is jobs[i]'s verdict: non-OK, it was refused and is
  // never called back. The accepted jobs take ONE place in the queue together (a tick of 64
  // characters waits as one frame, not 64): the compute threads take them side by side,
  // one job per thread at a time, a crowd job's instances one after another. A job whose
  // backend needs a team of threads (OpenCL on PoCL) is queued alone, as Submit would. Jobs
  // whose output is device memory (GPU regions), and float32 jobs of a backend that skins
  // frames together (BackendInfo::skins_frames_together: `opencl`), take one more place: a
  // few chunks of them, each chunk's frames handed to the backend together
  // (Backend::SkinFrames: on a GPU, one queue and waits that overlap the copies instead of
  // a lane and a wait per character).
  void SubmitGroup(SkinGroup* group, std::span<Status> statuses);
  // The same for a request and a callback (allocates the job: for tools and tests).
  Status Submit(SkinRequest request, SkinDone done);
  // Submit and wait: for tools and tests.
  Status SkinBlocking(SkinRequest request, FrameTiming* timing = nullptr);

  // The skeletons and clips that frames' poses name (SkinRequest.pose), content-addressed
  // and within options().clip_budget_bytes, beside the meshes.
  animation::AnimationStore& animations();
  const animation::AnimationStore& animations() const;

  EngineStats Stats() const;
  // Imports device memory into backend `backend` (an enabled, available one) for frames'
  // SkinRequest::device: the backend's ImportDeviceMemory, or INVALID_ARGUMENT naming the
  // backend when it is unknown or unavailable.
  Result<std::shared_ptr<DeviceMemory>> ImportDeviceMemory(const std::string& backend,
                                                           const DeviceMemoryImport& import);
  // Refuses new frames with UNAVAILABLE and waits for the queued ones to finish.
  void Shutdown();

 private:
  class Impl;
  static void RunPart(void* job, uint32_t instance, int threads);
  static void RunGroupPart(void* group, uint32_t part, int threads);
  static void RunTogetherGroupPart(void* group, uint32_t part, int threads);
  // After instance `instance` of `job` was skinned (or failed with `status`) into `frame`:
  // OnInstanceSkinned, and after the job's last instance its timing, counters and OnSkinned.
  static void FinishInstance(SkinJob& job, uint32_t instance, Status status,
                             const SkinFrame& frame);
  explicit Engine(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace skinserve
