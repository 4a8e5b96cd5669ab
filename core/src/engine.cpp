#include "skinserve/core/engine.h"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <exception>
#include <future>
#include <thread>

#include "compute_pool.h"
#include "mesh_store.h"
#include "skinserve/core/backend_registry.h"

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
  info.bytes = mesh.byte_size();
  info.normalized_vertices = mesh.normalized_vertices();
  return info;
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
        pool_(threads, options.queue_capacity) {
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

  Status Submit(SkinRequest request, SkinDone done) {
    if (shut_down_.load()) return Unavailable("the engine is shutting down");
    Result<std::size_t> backend_index = FindBackend(request.backend);
    if (!backend_index.ok()) return backend_index.status();
    if (Status s = CheckMethod(*backend_index, request.method); !s.ok()) return s;
    MeshStore::Lease entry = store_.Acquire(request.mesh_id);
    if (!entry) {
      return NotFound(
          fmt::format("mesh '{}' is not stored on this server; upload it again", request.mesh_id));
    }
    const SkinFrame frame{request.palette, request.positions, request.normals, request.method};
    if (Status s = frame.Validate(*entry->mesh()); !s.ok()) return s;

    Backend& backend = *backends_[*backend_index];
    const int64_t submitted = NowNs();
    auto task = [this, index = *backend_index, &backend, entry = std::move(entry),
                 request = std::move(request), done = std::move(done), submitted]() mutable {
      FrameTiming timing;
      const int64_t started = NowNs();
      timing.queued_ns = started - submitted;
      Status status = Run(index, backend, *entry, request);
      timing.compute_ns = NowNs() - started;
      entry.reset();  // unpin before the caller learns the frame is done
      done(std::move(status), timing);
    };
    if (!pool_.TrySubmit(backend.info().threads, std::move(task))) {
      if (shut_down_.load()) return Unavailable("the engine is shutting down");
      rejected_.fetch_add(1);
      return ResourceExhausted(fmt::format(
          "the compute queue is full ({} frames waiting); retry later or keep fewer frames in "
          "flight",
          pool_.capacity()));
    }
    return Status::Ok();
  }

  Status Run(std::size_t index, Backend& backend, MeshStore::Entry& entry,
             const SkinRequest& request) {
    Counters& counters = counters_[index];
    Status status;
    const int64_t started = NowNs();
    try {
      Result<const PreparedMesh*> prepared = entry.Prepared(index, backend);
      status = prepared.ok() ? backend.Skin(**prepared, {request.palette, request.positions,
                                                         request.normals, request.method})
                             : prepared.status();
    } catch (const std::exception& e) {
      status = Internal(fmt::format("backend '{}' failed: {}", backend.info().id, e.what()));
    }
    if (status.ok()) {
      counters.frames.fetch_add(1);
      counters.vertices.fetch_add(entry.mesh()->vertex_count());
      counters.compute_ns.fetch_add(NowNs() - started);
    } else {
      counters.errors.fetch_add(1);
    }
    return status;
  }

  EngineOptions options_;
  std::vector<std::unique_ptr<Backend>> backends_;
  std::vector<Counters> counters_;
  MeshStore store_;
  std::atomic<bool> shut_down_{false};
  std::atomic<uint64_t> rejected_{0};
  ComputePool pool_;  // last: its threads stop before the rest is destroyed
};

Result<std::unique_ptr<Engine>> Engine::Create(const EngineOptions& options) {
  int threads = options.compute_threads;
  if (threads <= 0) threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  std::vector<std::unique_ptr<Backend>> all = CreateAllBackends(threads);
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

std::vector<BackendInfo> Engine::Backends() const {
  std::vector<BackendInfo> infos;
  for (const auto& backend : impl_->backends_) infos.push_back(backend->info());
  return infos;
}

Status Engine::CheckMeshShape(uint64_t vertex_count, uint64_t influences, uint64_t joint_count,
                              bool has_normals) const {
  if (Status s =
          CheckMeshHeader(vertex_count, influences, joint_count, impl_->options_.mesh.limits);
      !s.ok()) {
    return s;
  }
  return impl_->store_.CheckFits(MeshByteSize(vertex_count, influences, has_normals));
}

Result<MeshInfo> Engine::AddMesh(const MeshArrays& arrays,
                                 std::optional<WeightPolicy> weight_policy) {
  if (Status s = CheckMeshShape(arrays.vertex_count, arrays.influences, arrays.joint_count,
                                !arrays.normals.empty());
      !s.ok()) {
    return s;
  }
  MeshOptions mesh_options = impl_->options_.mesh;
  if (weight_policy) mesh_options.weight_policy = *weight_policy;
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

bool Engine::DeleteMesh(const std::string& id) { return impl_->store_.Erase(id); }

Status Engine::Submit(SkinRequest request, SkinDone done) {
  return impl_->Submit(std::move(request), std::move(done));
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
  return stats;
}

void Engine::Shutdown() {
  impl_->shut_down_.store(true);
  impl_->pool_.Shutdown();
}

}  // namespace skinserve
