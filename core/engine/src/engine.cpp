#include "skinserve/engine/engine.h"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <exception>
#include <future>
#include <thread>

#include "compute_pool.h"
#include "device_output_checks.h"
#include "mesh_store.h"
#include "skinserve/engine/backend_registry.h"
#include "skinserve/model/aligned_buffer.h"
#include "skinserve/model/palette.h"

namespace skinserve {
namespace {

int64_t NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

MeshInfo DescribeMesh(const Mesh& mesh) {
  MeshInfo info;
  info.id = mesh.id();
  info.vertex_count = mesh.vertex_count();
  info.influences = mesh.influences();
  info.joint_count = mesh.joint_count();
  info.has_normals = mesh.has_normals();
  info.has_tangents = mesh.has_tangents();
  info.bytes = mesh.byte_size();
  info.normalized_vertices = mesh.normalized_vertices();
  info.morph_target_count = mesh.morph_target_count();
  info.rest_encoding = mesh.rest_encoding();
  return info;
}

// Per compute thread: where instances of skin_into_scratch jobs are skinned. It grows to
// the largest instance the thread has met (at most kMaxScratchFloatsPerInstance floats)
// and is reused for every later one, so it stays in that core's cache.
AlignedBuffer<float>& ThreadScratch(std::size_t floats) {
  thread_local AlignedBuffer<float> scratch;
  if (scratch.size() < floats) scratch = AlignedBuffer<float>(floats);
  return scratch;
}

}  // namespace

class Engine::Impl {
 public:
  struct Counters {
    std::atomic<uint64_t> frames{0}, vertices{0}, errors{0};
    std::atomic<int64_t> compute_ns{0};
  };

  Impl(const EngineOptions& options, int threads, std::vector<std::unique_ptr<Backend>> backends)
      : options_(options),
        backends_(std::move(backends)),
        counters_(backends_.size()),
        store_(options.mesh_budget_bytes, backends_.size()),
        animations_(options.clip_budget_bytes),
        pool_(threads, options.queue_capacity, options.split_min_vertices) {
    options_.compute_threads = threads;
  }

  // The index of backend `id` if it is enabled and available; else why not.
  Result<std::size_t> FindBackend(const std::string& id) const {
    std::string available;
    for (std::size_t i = 0; i < backends_.size(); ++i) {
      const BackendInfo& info = backends_[i]->info();
      if (info.id == id) {
        if (info.available) return i;
        return InvalidArgument(
            fmt::format("backend '{}' is not available here: {}", id, info.unavailable_reason));
      }
      if (info.available) available += (available.empty() ? "" : ", ") + info.id;
    }
    return InvalidArgument(
        fmt::format("backend '{}' is unknown; available backends: {}", id, available));
  }

  // OK when backend `index` implements `method`; else an error naming the backends that do.
  Status CheckMethod(std::size_t index, SkinningMethod method) const {
    const BackendInfo& info = backends_[index]->info();
    if (info.Supports(method)) return Status::Ok();
    std::string supporting;
    for (const auto& backend : backends_) {
      const BackendInfo& other = backend->info();
      if (other.available && other.Supports(method)) {
        supporting += (supporting.empty() ? "" : ", ") + other.id;
      }
    }
    return InvalidArgument(fmt::format(
        "backend '{}' does not implement method {} (it implements {}); backends here that do: {}",
        info.id, MethodName(method), MethodNames(info.methods),
        supporting.empty() ? "none" : supporting));
  }

  // The limits of a batch (Engine::CheckBatch).
  Status CheckBatch(uint32_t vertex_count, uint32_t instances) const {
    if (instances > options_.max_instances) {
      return InvalidArgument(
          fmt::format("instances = {} exceeds the limit of {} instances per request", instances,
                      options_.max_instances));
    }
    const uint64_t total_vertices = uint64_t{vertex_count} * std::max<uint32_t>(instances, 1);
    if (total_vertices > options_.mesh.limits.max_vertices) {
      return InvalidArgument(fmt::format(
          "instances * vertex_count = {} * {} = {} exceeds the limit of {} vertices per frame",
          instances, vertex_count, total_vertices, options_.mesh.limits.max_vertices));
    }
    return Status::Ok();
  }

  // The rest of a planned frame (its batch limits were Plan's): the palette's size, the
  // outputs' sizes and shape once for the whole batch, then each instance's palette values.
  static Status Check(const SkinRequest& request, const Mesh& mesh, uint32_t instances) {
    if (request.fill_inputs_on_run && instances > 1) {
      return InvalidArgument(fmt::format(
          "fill_inputs_on_run is set with instances = {}; a palette filled on the compute "
          "thread is one instance's",
          instances));
    }
    const std::size_t per_instance = 12ull * mesh.joint_count();
    if (instances > 1 && request.palette.size() != per_instance * instances) {
      const std::size_t whole = request.palette.size() / std::max<std::size_t>(per_instance, 1);
      return InvalidArgument(
          whole < instances
              ? fmt::format("palette holds {} floats: instance {}'s palette is missing or short "
                            "(a batch of {} instances of a mesh with {} joints needs 12 * {} * "
                            "{} = {} floats)",
                            request.palette.size(), whole, instances, mesh.joint_count(),
                            mesh.joint_count(), instances, per_instance * instances)
              : fmt::format("palette holds {} floats, more than the 12 * {} * {} = {} of a "
                            "batch of {} instances",
                            request.palette.size(), mesh.joint_count(), instances,
                            per_instance * instances, instances));
    }
    Status outputs = request.skin_into_scratch  ? CheckScratch(request, mesh)
                     : request.encoded.active() ? CheckEncodedSizes(request, mesh, instances)
                     : request.device.active()  ? CheckDeviceOutputs(request, mesh)
                                                : CheckFloatSizes(request, mesh, instances);
    if (!outputs.ok()) return outputs;
    return request.fill_inputs_on_run ? CheckPaletteToFill(request, mesh)
                                      : CheckPalettes(request, mesh, instances);
  }

  // Check() for fill_inputs_on_run: the room for the palette (its values come later).
  static Status CheckPaletteToFill(const SkinRequest& request, const Mesh& mesh) {
    const std::size_t expected = 12ull * mesh.joint_count();
    if (request.palette.size() == expected) return Status::Ok();
    return InvalidArgument(fmt::format(
        "palette to fill holds {} floats; expected 12 * joint_count = {} (joint_count {})",
        request.palette.size(), expected, mesh.joint_count()));
  }

  // fill_inputs_on_run, on the thread that skins the frame: the job writes the palette,
  // which is then checked as Submit checks a palette given up front.
  Status FillInputs(SkinJob& job) {
    Status status;
    try {
      status = job.FillInputs();
    } catch (const std::exception& e) {
      status = Internal(fmt::format("filling the frame's inputs: {}", e.what()));
    }
    if (!status.ok()) return status;
    const Mesh& mesh = *static_cast<MeshStore::Entry*>(job.lease_.get())->mesh();
    status = ValidateFramePalette(job.request.palette, job.request.method, mesh.joint_count());
    if (status.ok()) return status;
    return Status(status.code(),
                  fmt::format("the palette computed for the frame: {}", status.message()));
  }

  // Check() for float outputs: K instances' arrays, and what the mesh can give.
  static Status CheckFloatSizes(const SkinRequest& request, const Mesh& mesh, uint32_t instances) {
    const std::size_t outputs = 3ull * mesh.vertex_count();
    if (request.positions.size() != outputs * instances) {
      return InvalidArgument(fmt::format(
          "positions output holds {} floats; expected 3 * vertex_count * instances = {}",
          request.positions.size(), outputs * instances));
    }
    if (!request.normals.empty() && request.normals.size() != outputs * instances) {
      return InvalidArgument(
          fmt::format("normals output holds {} floats; expected 3 * vertex_count * instances = {}",
                      request.normals.size(), outputs * instances));
    }
    if (!request.tangents.empty() &&
        request.tangents.size() != 4ull * mesh.vertex_count() * instances) {
      return InvalidArgument(
          fmt::format("tangents output holds {} floats; expected 4 * vertex_count * instances = {}",
                      request.tangents.size(), 4ull * mesh.vertex_count() * instances));
    }
    return CheckOutputsAgainstMesh(!request.normals.empty(), !request.tangents.empty(), mesh);
  }

  // Each instance's palette values (its size was checked for the whole batch).
  static Status CheckPalettes(const SkinRequest& request, const Mesh& mesh, uint32_t instances) {
    const std::size_t per_instance = 12ull * mesh.joint_count();
    for (uint32_t i = 0; i < instances; ++i) {
      const std::span<const float> palette =
          instances == 1 ? request.palette
                         : request.palette.subspan(i * per_instance, per_instance);
      if (Status s = ValidateFramePalette(palette, request.method, mesh.joint_count()); !s.ok()) {
        if (instances == 1) return s;
        return Status(s.code(), fmt::format("instance {}: {}", i, s.message()));
      }
    }
    return Status::Ok();
  }

  // The frame's morph weights, once for all its instances, or each instance's own.
  static Status CheckMorph(const SkinRequest& request, const Mesh& mesh, const BackendInfo& info,
                           uint32_t instances) {
    if (request.instance_morph_weights.empty()) {
      if (Status s = ValidateMorphWeights(request.morph_weights, mesh.morph_target_count());
          !s.ok()) {
        return s;
      }
      return CheckMorphSupport(info, request.morph_weights);
    }
    if (request.instance_morph_weights.size() != instances || instances < 2) {
      return InvalidArgument(fmt::format(
          "instance_morph_weights holds {} entries; a crowd batch needs exactly one per "
          "instance ({}, at least 2)",
          request.instance_morph_weights.size(), instances));
    }
    if (!request.morph_weights.empty()) {
      return InvalidArgument(
          "instance_morph_weights and morph_weights are both set; give the weights either per "
          "instance or for the whole frame");
    }
    for (uint32_t i = 0; i < instances; ++i) {
      const std::span<const MorphWeight> weights = request.instance_morph_weights[i];
      Status s = ValidateMorphWeights(weights, mesh.morph_target_count());
      if (s.ok()) s = CheckMorphSupport(info, weights);
      if (!s.ok()) return Status(s.code(), fmt::format("instance {}: {}", i, s.message()));
    }
    return Status::Ok();
  }

  // A frame with encoded output: a backend that writes that encoding, no scratch.
  static Status CheckEncoded(const SkinRequest& request, const BackendInfo& info) {
    if (!request.encoded.active()) return Status::Ok();
    if (!info.WritesEncoding(request.encoded.encoding)) {
      return FailedPrecondition(
          fmt::format("backend '{}' does not write {} output itself (BackendInfo.encoded_outputs); "
                      "ask for float32 and encode the result",
                      info.id, VertexEncodingName(request.encoded.encoding)));
    }
    if (request.skin_into_scratch) {
      return InvalidArgument("encoded output and skin_into_scratch exclude each other");
    }
    return Status::Ok();
  }

  // Check() for skin_into_scratch: no output arrays; the instance fits the scratch.
  static Status CheckScratch(const SkinRequest& request, const Mesh& mesh) {
    if (!request.tangents.empty()) {
      return InvalidArgument(
          "skin_into_scratch: tangents are not skinned into scratch; ask for them with outputs");
    }
    if (!request.positions.empty() || !request.normals.empty()) {
      return InvalidArgument(
          "skin_into_scratch: positions and normals must be empty (each instance is skinned "
          "into its compute thread's scratch)");
    }
    if (Status s = CheckOutputsAgainstMesh(request.scratch_normals, false, mesh); !s.ok()) return s;
    const std::size_t floats = ScratchFloats(request, mesh);
    if (floats > kMaxScratchFloatsPerInstance) {
      return InvalidArgument(fmt::format(
          "skin_into_scratch: an instance of {} vertices needs {} floats, over the limit of {}",
          mesh.vertex_count(), floats, kMaxScratchFloatsPerInstance));
    }
    return Status::Ok();
  }

  // Check() for encoded output: K instances' bytes, K boxes; each instance's frame valid.
  static Status CheckEncodedSizes(const SkinRequest& request, const Mesh& mesh,
                                  uint32_t instances) {
    const EncodedOutput& e = request.encoded;
    if (!request.positions.empty() || !request.normals.empty() || !request.tangents.empty()) {
      return InvalidArgument(
          "a frame with encoded output has no float outputs (positions, normals, tangents empty)");
    }
    const std::size_t bytes = EncodedBytes(e.encoding, mesh.vertex_count());
    const std::size_t tangent_bytes = EncodedTangentBytes(e.encoding, mesh.vertex_count());
    if (e.positions.size() != bytes * instances ||
        (!e.normals.empty() && e.normals.size() != bytes * instances) ||
        (!e.tangents.empty() && e.tangents.size() != tangent_bytes * instances)) {
      return InvalidArgument(fmt::format(
          "encoded output holds {} / {} / {} bytes of positions / normals / tangents; {} "
          "instances of {} vertices in {} need {} / {} / {}",
          e.positions.size(), e.normals.size(), e.tangents.size(), instances, mesh.vertex_count(),
          VertexEncodingName(e.encoding), bytes * instances, bytes * instances,
          tangent_bytes * instances));
    }
    const std::size_t box_floats = 3ull * mesh.vertex_count() * instances;
    if (!e.box_scratch.empty() && e.box_scratch.size() != box_floats) {
      return InvalidArgument(fmt::format(
          "encoded output's box_scratch holds {} floats; {} instances of {} vertices need {}",
          e.box_scratch.size(), instances, mesh.vertex_count(), box_floats));
    }
    if (QuantizedToBox(e.encoding) && e.bounds == nullptr) {
      return InvalidArgument(fmt::format("encoded.bounds is null; {} needs each instance's box",
                                         VertexEncodingName(e.encoding)));
    }
    return CheckOutputsAgainstMesh(!e.normals.empty(), !e.tangents.empty(), mesh);
  }

  // Check() for device output (its ranges were CheckDeviceRequest's): what the mesh can give.
  static Status CheckDeviceOutputs(const SkinRequest& request, const Mesh& mesh) {
    return CheckOutputsAgainstMesh(request.device.normals, request.device.tangents, mesh);
  }

  static std::size_t ScratchFloats(const SkinRequest& request, const Mesh& mesh) {
    return ScratchFloatsPerInstance(mesh.vertex_count(), request.scratch_normals);
  }

  static SkinFrame InstanceFrame(const SkinRequest& request, const Mesh& mesh, uint32_t i,
                                 int threads = 0) {
    const std::size_t palette = 12ull * mesh.joint_count();
    const std::size_t outputs = 3ull * mesh.vertex_count();
    SkinFrame frame{request.palette.subspan(std::min(request.palette.size(), i * palette)),
                    std::span<float>(), std::span<float>(), std::span<float>(), threads};
    if (!request.skin_into_scratch && !request.encoded.active() && !request.device.active()) {
      frame.positions = request.positions.subspan(i * outputs, outputs);
      if (!request.normals.empty()) frame.normals = request.normals.subspan(i * outputs, outputs);
      const std::size_t tangents = 4ull * mesh.vertex_count();
      if (!request.tangents.empty()) {
        frame.tangents = request.tangents.subspan(i * tangents, tangents);
      }
    }
    if (request.encoded.active()) {
      const EncodedOutput& e = request.encoded;
      const std::size_t bytes = EncodedBytes(e.encoding, mesh.vertex_count());
      const std::size_t tangent_bytes = EncodedTangentBytes(e.encoding, mesh.vertex_count());
      frame.encoded.encoding = e.encoding;
      frame.encoded.positions = e.positions.subspan(std::min(e.positions.size(), i * bytes));
      frame.encoded.positions = frame.encoded.positions.first(
          std::min(frame.encoded.positions.size(), bytes));  // sizes checked
      if (!e.normals.empty()) frame.encoded.normals = e.normals.subspan(i * bytes, bytes);
      if (!e.tangents.empty()) {
        frame.encoded.tangents = e.tangents.subspan(i * tangent_bytes, tangent_bytes);
      }
      if (e.bounds != nullptr) frame.encoded.bounds = e.bounds + i;
      if (!e.box_scratch.empty())
        frame.encoded.box_scratch = e.box_scratch.subspan(i * outputs, outputs);
    }
    frame.device = InstanceDeviceOutput(request, i);
    frame.method = request.method;
    frame.morph_weights = request.instance_morph_weights.empty()
                              ? request.morph_weights
                              : request.instance_morph_weights[i];
    if (request.instances > 1) frame.palette = frame.palette.first(palette);  // sizes checked
    return frame;
  }

  Status Plan(SkinJob* job) {
    const SkinRequest& request = job->request;
    Result<std::size_t> backend_index = FindBackend(request.backend);
    if (!backend_index.ok()) return backend_index.status();
    if (Status s = CheckMethod(*backend_index, request.method); !s.ok()) return s;
    MeshStore::Lease entry = store_.Acquire(request.mesh_id);
    if (!entry) {
      return NotFound(
          fmt::format("mesh '{}' is not stored on this server; upload it again", request.mesh_id));
    }
    const Mesh& mesh = *entry->mesh();
    if (Status s = CheckBatch(mesh.vertex_count(), std::max<uint32_t>(request.instances, 1));
        !s.ok()) {
      return s;
    }
    job->backend_index_ = *backend_index;
    job->lease_ = std::move(entry);
    plans_built_.fetch_add(1, std::memory_order_relaxed);
    job->plan_ = {.planned = true,
                  .instances = std::max<uint32_t>(request.instances, 1),
                  .vertex_count = mesh.vertex_count(),
                  .joint_count = mesh.joint_count(),
                  .has_normals = mesh.has_normals(),
                  .has_tangents = mesh.has_tangents(),
                  .morph_target_count = mesh.morph_target_count(),
                  .backend_encodings = EncodingMask(backends_[*backend_index]->info()),
                  .backend_box_scratch = backends_[*backend_index]->info().encoded_box_scratch};
    return Status::Ok();
  }

  bool Reuse(const KeptPlan& kept, SkinJob* job) {
    if (!kept.kept()) return false;
    std::shared_ptr<void> lease = kept.mesh_.lock();
    if (lease == nullptr) return false;  // deleted or evicted, and no frame holds it
    auto& entry = *static_cast<MeshStore::Entry*>(lease.get());
    if (!entry.stored()) return false;  // deleted or evicted while a frame held it
    entry.MarkUsed();
    plans_reused_.fetch_add(1, std::memory_order_relaxed);
    job->lease_ = std::move(lease);
    job->plan_ = kept.plan_;
    job->backend_index_ = kept.backend_index_;
    return true;
  }

  Status Submit(SkinJob* job, void (*run)(void*, uint32_t, int), bool allow_inline = false) {
    if (shut_down_.load()) {
      job->DropPlan();
      return Unavailable("the engine is shutting down");
    }
    if (!job->plan_.planned) {
      if (Status s = Plan(job); !s.ok()) return s;
    }
    Status status = Queue(job, run, allow_inline);
    if (!status.ok()) job->DropPlan();
    return status;
  }

  // Queues a planned job once the rest of its request is checked.
  Status Queue(SkinJob* job, void (*run)(void*, uint32_t, int), bool allow_inline) {
    ComputePool::Task task;
    if (Status s = Admit(job, run, &task); !s.ok()) return s;
    if (allow_inline && pool_.TryRunInline(task)) return Status::Ok();
    return Enqueue(task);
  }

  Status Enqueue(const ComputePool::Task& task) {
    if (pool_.TrySubmit(task)) return Status::Ok();
    if (shut_down_.load()) return Unavailable("the engine is shutting down");
    rejected_.fetch_add(1);
    return ResourceExhausted(fmt::format(
        "the compute queue is full ({} frames waiting); retry later or keep fewer frames in "
        "flight",
        pool_.capacity()));
  }

  void SubmitGroup(SkinGroup* group, std::span<Status> statuses,
                   void (*run_part)(void*, uint32_t, int), void (*run_group)(void*, uint32_t, int),
                   void (*run_together)(void*, uint32_t, int)) {
    group->queued_.clear();
    group->together_.clear();
    int together_width = 1;
    for (std::size_t i = 0; i < group->jobs.size(); ++i) {
      SkinJob* job = group->jobs[i];
      Status& status = statuses[i];
      status = shut_down_.load() ? Unavailable("the engine is shutting down") : Status::Ok();
      if (status.ok() && !job->plan_.planned) status = Plan(job);
      ComputePool::Task task;
      if (status.ok()) status = Admit(job, run_part, &task);
      if (status.ok() && SkinsTogether(*job)) {
        group->together_.push_back(job);
        together_width = std::max(together_width, task.min_width);
      } else if (status.ok() && std::min(task.min_width, pool_.size()) > 1) {
        status = Enqueue(task);  // a team's job: alone, as Submit queues it
      } else if (status.ok()) {
        group->queued_.push_back(job);
      }
      if (!status.ok()) job->DropPlan();
    }
    EnqueueGroupTask(group, &group->queued_, run_group,
                     static_cast<uint32_t>(group->queued_.size()), 1, statuses);
    // Chunks of at least 8 frames, at most one per compute thread.
    const auto together_parts = static_cast<uint32_t>(std::clamp<std::size_t>(
        group->together_.size() / 8, 1, static_cast<std::size_t>(pool_.size())));
    group->together_parts_ = together_parts;
    EnqueueGroupTask(group, &group->together_, run_together, together_parts, together_width,
                     statuses);
  }

  // Whether a group's accepted `job` goes to the backend with the others of its chunk
  // (Backend::SkinFrames): output in device memory always; float32 output in host memory
  // when its backend skins such frames together (BackendInfo::skins_frames_together).
  bool SkinsTogether(const SkinJob& job) const {
    const SkinRequest& request = job.request;
    if (request.device.active()) return true;
    return backends_[job.backend_index_]->info().skins_frames_together &&
           !request.encoded.active() && !request.skin_into_scratch;
  }

  // One task of `group` running `jobs` (its queued_ or together_) in `parts` parts; if the
  // queue refuses it, each of those jobs' statuses says so and `jobs` is emptied.
  void EnqueueGroupTask(SkinGroup* group, std::vector<SkinJob*>* jobs,
                        void (*run)(void*, uint32_t, int), uint32_t parts, int width,
                        std::span<Status> statuses) {
    if (jobs->empty()) return;
    ComputePool::Task task;
    task.run = run;
    task.context = group;
    task.parts = parts;
    task.min_width = task.max_width = width;
    if (Status s = Enqueue(task); !s.ok()) {
      for (std::size_t i = 0; i < group->jobs.size(); ++i) {
        if (std::find(jobs->begin(), jobs->end(), group->jobs[i]) == jobs->end()) continue;
        statuses[i] = s;
        group->jobs[i]->DropPlan();
      }
      jobs->clear();
    }
  }

  // A chunk of a group's jobs skinned together (SkinGroup::together_) on one compute thread of
  // `threads`: every instance of every job a frame, the frames of each backend handed to it
  // together (Backend::SkinFrames), then each instance finished as RunPart does. A
  // job whose inputs or mesh fail fails each of its instances.
  void RunTogether(std::span<SkinJob* const> jobs, int threads) {
    const int64_t started = NowNs();
    std::vector<std::pair<SkinJob*, uint32_t>> items;  // job, instance
    std::vector<SkinFrame> frames;
    std::vector<const PreparedMesh*> prepared;
    std::vector<Status> statuses;
    for (SkinJob* job : jobs) {
      int64_t unset = 0;
      job->started_ns_.compare_exchange_strong(unset, started);
      Result<const PreparedMesh*> mesh = PreparedFor(*job);
      Status status = job->request.fill_inputs_on_run ? FillInputs(*job) : mesh.status();
      if (status.ok()) status = mesh.status();
      const Mesh& whole = *static_cast<MeshStore::Entry*>(job->lease_.get())->mesh();
      for (uint32_t i = 0; i < std::max<uint32_t>(job->request.instances, 1); ++i) {
        items.emplace_back(job, i);
        frames.push_back(InstanceFrame(job->request, whole, i, threads));
        prepared.push_back(mesh.ok() ? *mesh : nullptr);
        statuses.push_back(status);
      }
    }
    std::vector<DeviceTiming> timings(frames.size());
    for (std::size_t k = 0; k < frames.size(); ++k) frames[k].device_timing = &timings[k];
    SkinTogether(items, prepared, frames, statuses);
    const int64_t finished = NowNs();
    const int64_t each =
        (finished - started) / static_cast<int64_t>(std::max<std::size_t>(frames.size(), 1));
    // Each job's compute (FrameTiming::compute_ns) is its share of the chunk's time, not the
    // whole chunk's: a tick's summed compute is then what the chunks took. The rest of its
    // wait counts as queued.
    for (SkinJob* job : jobs) {
      const int64_t instances = std::max<uint32_t>(job->request.instances, 1);
      job->started_ns_.store(finished - each * instances);
    }
    for (std::size_t k = 0; k < items.size(); ++k) {
      SkinJob& job = *items[k].first;
      job.device_transfer_ns_.fetch_add(timings[k].transfer_ns);
      job.device_kernel_ns_.fetch_add(timings[k].kernel_ns);
      if (statuses[k].ok()) {
        counters_[job.backend_index_].vertices.fetch_add(job.vertex_count_);
        counters_[job.backend_index_].compute_ns.fetch_add(each);
      }
      // The job's last instance may reuse it: nothing of it after this.
      Engine::FinishInstance(job, items[k].second, std::move(statuses[k]), frames[k]);
    }
  }

  // `job`'s mesh as its backend prepared it (preparing it now if it was not).
  Result<const PreparedMesh*> PreparedFor(SkinJob& job) {
    Backend& backend = *backends_[job.backend_index_];
    auto& entry = *static_cast<MeshStore::Entry*>(job.lease_.get());
    try {
      bool built = false;
      Result<const PreparedMesh*> prepared = entry.Prepared(job.backend_index_, backend, &built);
      if (built && options_.after_prepare) options_.after_prepare();
      return prepared;
    } catch (const std::exception& e) {
      return Internal(fmt::format("backend '{}' failed: {}", backend.info().id, e.what()));
    }
  }

  // RunTogether's frames whose status is OK so far, each backend's handed to it at once.
  void SkinTogether(std::span<const std::pair<SkinJob*, uint32_t>> items,
                    std::span<const PreparedMesh* const> prepared,
                    std::span<const SkinFrame> frames, std::span<Status> statuses) {
    std::vector<std::size_t> picked;
    std::vector<const PreparedMesh*> meshes;
    std::vector<SkinFrame> chosen;
    std::vector<Status> verdicts;
    std::vector<bool> done(items.size(), false);
    for (std::size_t first = 0; first < items.size(); ++first) {
      if (done[first] || !statuses[first].ok()) continue;
      const std::size_t backend = items[first].first->backend_index_;
      picked.clear();
      meshes.clear();
      chosen.clear();
      for (std::size_t k = first; k < items.size(); ++k) {
        if (done[k] || !statuses[k].ok() || items[k].first->backend_index_ != backend) continue;
        done[k] = true;
        picked.push_back(k);
        meshes.push_back(prepared[k]);
        chosen.push_back(frames[k]);
      }
      verdicts.assign(picked.size(), Status::Ok());
      try {
        backends_[backend]->SkinFrames(meshes, chosen, verdicts);
      } catch (const std::exception& e) {
        verdicts.assign(picked.size(),
                        Internal(fmt::format("backend '{}' failed: {}",
                                             backends_[backend]->info().id, e.what())));
      }
      for (std::size_t j = 0; j < picked.size(); ++j) statuses[picked[j]] = std::move(verdicts[j]);
    }
  }

  // Checks a planned job's request and readies its bookkeeping and its pool task.
  Status Admit(SkinJob* job, void (*run)(void*, uint32_t, int), ComputePool::Task* task) {
    const SkinRequest& request = job->request;
    auto& entry = *static_cast<MeshStore::Entry*>(job->lease_.get());
    const Mesh& mesh = *entry.mesh();
    const uint32_t instances = std::max<uint32_t>(request.instances, 1);
    if (instances != job->plan_.instances) {  // the batch limits held for the planned size
      return InvalidArgument(
          fmt::format("instances = {} differs from the {} the frame was planned with", instances,
                      job->plan_.instances));
    }
    const BackendInfo& info = backends_[job->backend_index_]->info();
    if (Status s = CheckMorph(request, mesh, info, instances); !s.ok()) return s;
    if (Status s = CheckTangentSupport(info, !request.tangents.empty() ||
                                                 !request.encoded.tangents.empty() ||
                                                 request.device.tangents);
        !s.ok()) {
      return s;
    }
    if (Status s = CheckEncoded(request, info); !s.ok()) return s;
    if (request.device.active()) {
      if (Status s = CheckDeviceRequest(request, mesh, instances, info); !s.ok()) return s;
    }
    if (Status s = Check(request, mesh, instances); !s.ok()) return s;

    job->engine_ = this;
    job->vertex_count_ = mesh.vertex_count();
    job->submitted_ns_ = NowNs();
    job->started_ns_.store(0);
    job->remaining_.store(instances);
    job->status_ = Status::Ok();
    task->run = run;
    task->context = job;
    task->parts = instances;
    task->max_width = info.threads;
    task->min_width = info.min_threads > 0 ? info.min_threads : info.threads;
    task->work = mesh.vertex_count();
    return Status::Ok();
  }

  // Skins instance `i` of `job` on `threads` threads into `*frame` (its outputs are what
  // OnInstanceSkinned gets).
  Status RunInstance(SkinJob& job, uint32_t i, int threads, SkinFrame* frame) {
    Backend& backend = *backends_[job.backend_index_];
    auto& entry = *static_cast<MeshStore::Entry*>(job.lease_.get());
    Counters& counters = counters_[job.backend_index_];
    Status status;
    const int64_t started = NowNs();
    try {
      bool built = false;
      Result<const PreparedMesh*> prepared = entry.Prepared(job.backend_index_, backend, &built);
      if (built && options_.after_prepare) options_.after_prepare();
      DeviceTiming device;
      const Mesh& mesh = *entry.mesh();
      *frame = InstanceFrame(job.request, mesh, i, threads);
      if (job.request.skin_into_scratch) {
        const std::size_t outputs = 3ull * mesh.vertex_count();
        const std::size_t floats = ScratchFloats(job.request, mesh);
        float* scratch = ThreadScratch(floats).data();
        frame->positions = {scratch, outputs};
        if (job.request.scratch_normals) frame->normals = {scratch + floats - outputs, outputs};
      }
      frame->device_timing = &device;
      status = prepared.ok() ? backend.Skin(**prepared, *frame) : prepared.status();
      job.device_transfer_ns_.fetch_add(device.transfer_ns);
      job.device_kernel_ns_.fetch_add(device.kernel_ns);
    } catch (const std::exception& e) {
      status = Internal(fmt::format("backend '{}' failed: {}", backend.info().id, e.what()));
    }
    if (status.ok()) {
      counters.vertices.fetch_add(job.vertex_count_);
      counters.compute_ns.fetch_add(NowNs() - started);
    }
    return status;
  }

  EngineOptions options_;
  std::vector<std::unique_ptr<Backend>> backends_;
  std::vector<Counters> counters_;
  MeshStore store_;
  animation::AnimationStore animations_;
  std::atomic<bool> shut_down_{false};
  std::atomic<uint64_t> rejected_{0};
  std::atomic<uint64_t> plans_built_{0}, plans_reused_{0};
  ComputePool pool_;  // last: its threads stop before the rest is destroyed
};

Result<std::unique_ptr<Engine>> Engine::Create(const EngineOptions& options) {
  int threads = options.compute_threads;
  if (threads <= 0) threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  std::vector<std::unique_ptr<Backend>> all =
      CreateAllBackends(threads, options.opencl_device, options.opencl_device_timing);
  if (!options.opencl_device.empty()) {
    // The operator chose a device: not finding it is a start-up error, not a warning.
    for (const auto& b : all) {
      if (b->info().id == "opencl" && !b->info().available) {
        return FailedPrecondition(b->info().unavailable_reason);
      }
    }
  }
  std::vector<std::unique_ptr<Backend>> enabled;
  if (options.enabled_backends.empty()) {
    enabled = std::move(all);
  } else {
    for (const std::string& id : options.enabled_backends) {
      auto it = std::find_if(all.begin(), all.end(),
                             [&](const auto& b) { return b && b->info().id == id; });
      if (it == all.end()) {
        std::string known;
        for (const auto& b : all) {
          if (b) known += (known.empty() ? "" : ", ") + b->info().id;
        }
        return InvalidArgument(
            fmt::format("enabled backend '{}' is unknown or listed twice; known: {}", id, known));
      }
      enabled.push_back(std::move(*it));
    }
  }
  return std::unique_ptr<Engine>(
      new Engine(std::make_unique<Impl>(options, threads, std::move(enabled))));
}

Engine::Engine(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Engine::~Engine() { Shutdown(); }

const EngineOptions& Engine::options() const { return impl_->options_; }

animation::AnimationStore& Engine::animations() { return impl_->animations_; }
const animation::AnimationStore& Engine::animations() const { return impl_->animations_; }

Result<std::shared_ptr<DeviceMemory>> Engine::ImportDeviceMemory(const std::string& backend,
                                                                 const DeviceMemoryImport& import) {
  Result<std::size_t> index = impl_->FindBackend(backend);
  if (!index.ok()) return index.status();
  return impl_->backends_[*index]->ImportDeviceMemory(import);
}

std::vector<BackendInfo> Engine::Backends() const {
  std::vector<BackendInfo> infos;
  for (const auto& backend : impl_->backends_) infos.push_back(backend->info());
  return infos;
}

Status Engine::CheckMeshShape(uint64_t vertex_count, uint64_t influences, uint64_t joint_count,
                              bool has_normals, std::span<const uint32_t> morph_target_sizes,
                              bool morph_normals, RestEncoding rest_encoding, bool has_tangents,
                              bool morph_tangents) const {
  const MeshLimits& limits = impl_->options_.mesh.limits;
  if (Status s = CheckMeshHeader(vertex_count, influences, joint_count, limits); !s.ok()) {
    return s;
  }
  if (Status s = CheckMorphHeader(morph_target_sizes, vertex_count, has_normals, morph_normals,
                                  limits, has_tangents, morph_tangents);
      !s.ok()) {
    return s;
  }
  if (Status s = CheckRestEncoding(rest_encoding, morph_target_sizes.size()); !s.ok()) return s;
  uint64_t deltas = 0;
  for (uint32_t size : morph_target_sizes) deltas += size;
  return impl_->store_.CheckFits(
      MeshByteSize(vertex_count, influences, has_normals, morph_target_sizes.size(), deltas,
                   morph_normals, rest_encoding, joint_count, has_tangents, morph_tangents));
}

Result<MeshInfo> Engine::AddMesh(const MeshArrays& arrays,
                                 std::optional<WeightPolicy> weight_policy,
                                 RestEncoding rest_encoding) {
  if (Status s = CheckMeshShape(arrays.vertex_count, arrays.influences, arrays.joint_count,
                                !arrays.normals.empty(), arrays.morph_target_sizes,
                                !arrays.morph_normal_deltas.empty(), rest_encoding,
                                !arrays.tangents.empty(), !arrays.morph_tangent_deltas.empty());
      !s.ok()) {
    return s;
  }
  MeshOptions mesh_options = impl_->options_.mesh;
  if (weight_policy) mesh_options.weight_policy = *weight_policy;
  mesh_options.rest_encoding = rest_encoding;
  auto mesh = Mesh::Create(arrays, mesh_options);
  if (!mesh.ok()) return mesh.status();
  bool already_stored = false;
  if (Status s = impl_->store_.Insert(*mesh, &already_stored); !s.ok()) return s;
  MeshInfo info = DescribeMesh(**mesh);
  info.already_stored = already_stored;
  return info;
}

Result<MeshInfo> Engine::GetMesh(const std::string& id) const {
  MeshStore::Lease entry = impl_->store_.Acquire(id);
  if (!entry) {
    return NotFound(fmt::format("mesh '{}' is not stored on this server; upload it again", id));
  }
  MeshInfo info = DescribeMesh(*entry->mesh());
  info.already_stored = true;
  return info;
}

Status Engine::GetMesh(const std::string& id, MeshInfo* info) const {
  MeshStore::Lease entry = impl_->store_.Acquire(id);
  if (!entry) {
    return NotFound(fmt::format("mesh '{}' is not stored on this server; upload it again", id));
  }
  const Mesh& mesh = *entry->mesh();
  info->id.assign(mesh.id());
  info->vertex_count = mesh.vertex_count();
  info->influences = mesh.influences();
  info->joint_count = mesh.joint_count();
  info->has_normals = mesh.has_normals();
  info->has_tangents = mesh.has_tangents();
  info->bytes = mesh.byte_size();
  info->normalized_vertices = mesh.normalized_vertices();
  info->morph_target_count = mesh.morph_target_count();
  info->rest_encoding = mesh.rest_encoding();
  info->already_stored = true;
  return Status::Ok();
}

Status Engine::CheckBatch(uint32_t vertex_count, uint32_t instances) const {
  return impl_->CheckBatch(vertex_count, instances);
}

bool Engine::DeleteMesh(const std::string& id) { return impl_->store_.Erase(id); }

Status Engine::Plan(SkinJob* job) { return impl_->Plan(job); }

void Engine::Keep(const SkinJob& job, KeptPlan* kept) const {
  kept->mesh_ = job.lease_;
  kept->plan_ = job.plan_;
  kept->backend_index_ = job.backend_index_;
}

bool Engine::Reuse(const KeptPlan& kept, SkinJob* job) { return impl_->Reuse(kept, job); }

Status Engine::Submit(SkinJob* job) { return impl_->Submit(job, &Engine::RunPart); }

void Engine::SubmitGroup(SkinGroup* group, std::span<Status> statuses) {
  impl_->SubmitGroup(group, statuses, &Engine::RunPart, &Engine::RunGroupPart,
                     &Engine::RunTogetherGroupPart);
}

void Engine::RunTogetherGroupPart(void* context, uint32_t part, int threads) {
  auto& group = *static_cast<SkinGroup*>(context);
  // Contiguous chunks; read first: a job's last instance may reuse the group.
  const std::size_t n = group.together_.size(), parts = group.together_parts_;
  const std::size_t begin = n * part / parts, end = n * (part + 1) / parts;
  std::vector<SkinJob*> chunk(group.together_.begin() + static_cast<std::ptrdiff_t>(begin),
                              group.together_.begin() + static_cast<std::ptrdiff_t>(end));
  if (chunk.empty()) return;
  static_cast<Impl*>(chunk.front()->engine_)->RunTogether(chunk, threads);
}

void Engine::RunGroupPart(void* context, uint32_t part, int threads) {
  SkinJob* job = static_cast<SkinGroup*>(context)->queued_[part];
  // Read first: the last instance's OnSkinned may reuse the job.
  const uint32_t instances = std::max<uint32_t>(job->request.instances, 1);
  for (uint32_t i = 0; i < instances; ++i) RunPart(job, i, threads);
}

Status Engine::Run(SkinJob* job) {
  return impl_->Submit(job, &Engine::RunPart, /*allow_inline=*/true);
}

void Engine::RunPart(void* context, uint32_t instance, int threads) {
  auto& job = *static_cast<SkinJob*>(context);
  auto& impl = *static_cast<Impl*>(job.engine_);
  int64_t unset = 0;
  job.started_ns_.compare_exchange_strong(unset, NowNs());
  SkinFrame frame;
  // A palette filled on this thread: only single-instance frames (Admit), so once a frame.
  Status status = job.request.fill_inputs_on_run ? impl.FillInputs(job) : Status::Ok();
  if (status.ok()) status = impl.RunInstance(job, instance, threads, &frame);
  FinishInstance(job, instance, std::move(status), frame);
}

void Engine::FinishInstance(SkinJob& job, uint32_t instance, Status status,
                            const SkinFrame& frame) {
  auto& impl = *static_cast<Impl*>(job.engine_);
  if (!status.ok() && job.request.encoded.active() && job.request.instances > 1) {
    // The backend encoded (and refused a value of) this instance: say which one, as the
    // server does for what it encodes itself.
    status = Status(status.code(), fmt::format("instance {}: {}", instance, status.message()));
  }
  if (status.ok()) {
    try {
      status = job.OnInstanceSkinned(instance, frame.positions, frame.normals);
    } catch (const std::exception& e) {
      status = Internal(fmt::format("after skinning instance {}: {}", instance, e.what()));
    }
  }
  if (!status.ok()) {
    std::lock_guard lock(job.status_mutex_);
    if (job.status_.ok()) job.status_ = std::move(status);
  }
  if (job.remaining_.fetch_sub(1) != 1) return;
  // The last instance: the frame is done.
  FrameTiming timing;
  const int64_t started = job.started_ns_.load();
  timing.queued_ns = started - job.submitted_ns_;
  timing.compute_ns = NowNs() - started;
  timing.device_transfer_ns = job.device_transfer_ns_.exchange(0);  // summed over instances
  timing.device_kernel_ns = job.device_kernel_ns_.exchange(0);
  Impl::Counters& counters = impl.counters_[job.backend_index_];
  (job.status_.ok() ? counters.frames : counters.errors).fetch_add(1);
  job.lease_.reset();  // unpin before the caller learns the frame is done
  job.plan_ = {};
  Status result = std::move(job.status_);
  job.status_ = Status::Ok();
  job.OnSkinned(std::move(result), timing);  // may reuse or delete the job: nothing after
}

namespace {

// Engine::Submit(request, done): a job that owns its request and deletes itself.
class CallbackJob final : public SkinJob {
 public:
  explicit CallbackJob(SkinDone done) : done_(std::move(done)) {}

 private:
  void OnSkinned(Status status, const FrameTiming& timing) override {
    SkinDone done = std::move(done_);
    delete this;
    done(std::move(status), timing);
  }
  SkinDone done_;
};

}  // namespace

Status Engine::Submit(SkinRequest request, SkinDone done) {
  if (request.skin_into_scratch) {
    return InvalidArgument("skin_into_scratch needs a SkinJob to take each instance's output");
  }
  if (request.fill_inputs_on_run) {
    return InvalidArgument("fill_inputs_on_run needs a SkinJob to fill the palette");
  }
  auto* job = new CallbackJob(std::move(done));
  job->request = std::move(request);
  Status status = Submit(job);
  if (!status.ok()) delete job;
  return status;
}

Status Engine::SkinBlocking(SkinRequest request, FrameTiming* timing) {
  std::promise<std::pair<Status, FrameTiming>> result;
  auto future = result.get_future();
  Status submitted = Submit(std::move(request), [&result](Status status, FrameTiming t) {
    result.set_value({std::move(status), t});
  });
  if (!submitted.ok()) return submitted;
  auto [status, t] = future.get();
  if (timing != nullptr) *timing = t;
  return status;
}

EngineStats Engine::Stats() const {
  EngineStats stats;
  for (std::size_t i = 0; i < impl_->backends_.size(); ++i) {
    const auto& c = impl_->counters_[i];
    stats.backends.push_back({impl_->backends_[i]->info().id, c.frames.load(), c.vertices.load(),
                              c.errors.load(), c.compute_ns.load()});
  }
  stats.queue_depth = impl_->pool_.depth();
  stats.queue_capacity = impl_->pool_.capacity();
  stats.compute_threads = impl_->pool_.size();
  stats.meshes = impl_->store_.count();
  stats.mesh_bytes = impl_->store_.bytes();
  stats.mesh_budget_bytes = impl_->store_.budget_bytes();
  stats.evictions = impl_->store_.evictions();
  stats.rejected_queue_full = impl_->rejected_.load();
  stats.peak_busy_threads = impl_->pool_.peak_busy();
  stats.inline_frames = impl_->pool_.inline_runs();
  stats.plans_built = impl_->plans_built_.load(std::memory_order_relaxed);
  stats.plans_reused = impl_->plans_reused_.load(std::memory_order_relaxed);
  return stats;
}

void Engine::Shutdown() {
  impl_->shut_down_.store(true);
  impl_->pool_.Shutdown();
}

}  // namespace skinserve
