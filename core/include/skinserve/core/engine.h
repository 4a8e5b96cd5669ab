// Engine: the backends by id, the mesh store and the compute threads. Usable in-process;
// the server is a thin translation of wire messages onto it.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "skinserve/core/backend.h"
#include "skinserve/core/mesh.h"
#include "skinserve/core/status.h"

namespace skinserve {

struct EngineOptions {
  int compute_threads = 0;                    // 0: one per core
  std::size_t queue_capacity = 256;           // frames waiting for a compute thread
  uint64_t mesh_budget_bytes = 4ull << 30;    // LRU eviction beyond this
  MeshOptions mesh;                           // limits and weight policy on ingest
  std::vector<std::string> enabled_backends;  // ids; empty: all
};

struct MeshInfo {
  std::string id;
  uint32_t vertex_count = 0;
  uint32_t influences = 0;
  uint32_t joint_count = 0;
  bool has_normals = false;
  uint64_t bytes = 0;
  uint32_t normalized_vertices = 0;
  bool already_stored = false;  // the same content was stored before (dedupe)
};

// Server-side time of one frame, for the wire's timing breakdown.
struct FrameTiming {
  int64_t queued_ns = 0;   // from Submit until a compute thread took it
  int64_t compute_ns = 0;  // the backend's Skin call
};

// One frame to skin. The outputs are caller-owned and must stay valid until `done` runs.
struct SkinRequest {
  std::string mesh_id;
  std::string backend;
  std::vector<float> palette;                       // 12 * joint_count floats
  std::span<float> positions;                       // 3 * vertex_count
  std::span<float> normals;                         // empty: no normals
  SkinningMethod method = SkinningMethod::kLinear;  // the backend must list it
};
using SkinDone = std::function<void(Status, FrameTiming)>;

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
  // array is received or allocated (INVALID_ARGUMENT or RESOURCE_EXHAUSTED).
  Status CheckMeshShape(uint64_t vertex_count, uint64_t influences, uint64_t joint_count,
                        bool has_normals) const;
  // Validates and stores a mesh (dedupe by content id; LRU eviction beyond the budget).
  // `weight_policy` overrides the engine's (options().mesh) for this mesh.
  Result<MeshInfo> AddMesh(const MeshArrays& arrays,
                           std::optional<WeightPolicy> weight_policy = std::nullopt);
  Result<MeshInfo> GetMesh(const std::string& id) const;
  bool DeleteMesh(const std::string& id);

  // Checks the request (unknown mesh: NOT_FOUND; unknown or unavailable backend, a
  // method the backend lacks, bad palette (for dual-quaternion: a joint that is not
  // rigid) or output sizes: INVALID_ARGUMENT; full queue: RESOURCE_EXHAUSTED; shut down:
  // UNAVAILABLE) and queues it. On OK, `done` is called exactly once, on a compute
  // thread; on an error, `done` is never called.
  Status Submit(SkinRequest request, SkinDone done);
  // Submit and wait: for tools and tests.
  Status SkinBlocking(SkinRequest request, FrameTiming* timing = nullptr);

  EngineStats Stats() const;
  // Refuses new frames with UNAVAILABLE and waits for the queued ones to finish.
  void Shutdown();

 private:
  class Impl;
  explicit Engine(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace skinserve
