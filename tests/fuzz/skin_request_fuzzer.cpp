// A StreamSkin/Skin frame from raw wire bytes: the input is one SkinRequest message. It
// goes the server's way: FrameJob::Prepare (mesh lookup, backend, palette bytes decoded),
// the engine (palette validated against the mesh's joints, skinned on `serial`), then the
// answer cut into serialized response parts (slices of the job's wire buffer), which must
// parse as SkinResponse messages and cover the mesh's vertices exactly once; once the job
// lets go of its parts, gRPC's hold on the wire buffer must be released.
// mesh_id "m" stands for the mesh stored at start-up, so inputs can reach the skinning.
#include <grpcpp/impl/codegen/proto_utils.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <cstdlib>
#include <map>
#include <mutex>

#include "frames/frame_job.h"
#include "frames/inflight_budget.h"
#include "fuzz_engine.h"
#include "skinserve/reference/synthetic.h"

using namespace skinserve;

namespace {

const std::string& StoredMeshId() {
  static const std::string id = [] {
    SyntheticMeshSpec spec;
    spec.vertex_count = 300;
    spec.influences = 4;
    spec.joint_count = 8;
    spec.normals = true;
    auto info = fuzz::FuzzEngine().AddMesh(MakeSyntheticMesh(spec), WeightPolicy::kReject);
    if (!info.ok()) std::abort();
    return info->id;
  }();
  return id;
}

// Waits for the engine's verdict on a job (OnFrameDone runs on a compute thread).
class DoneListener final : public server::FrameJob::Listener {
 public:
  void OnFrameDone(server::StreamAnswer*) override {
    std::lock_guard lock(mutex_);
    done_ = true;
    changed_.notify_all();
  }
  void OnPartsReady(server::StreamAnswer*) override {}  // early parts: read after the frame
  void HoldForWire() override { holds.fetch_add(1); }
  void ReleaseForWire() override { holds.fetch_sub(1); }
  void Wait() {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return done_; });
  }
  std::atomic<int> holds{0};

 private:
  std::mutex mutex_;
  std::condition_variable changed_;
  bool done_ = false;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  Engine& engine = fuzz::FuzzEngine();
  v1::SkinRequest wire;
  if (!wire.ParseFromArray(data, static_cast<int>(size))) return 0;
  if (wire.mesh_id() == "m") wire.set_mesh_id(StoredMeshId());
  static server::InflightBudget budget(256ull << 20);
  DoneListener listener;
  server::FrameJob job(&listener, &budget);
  server::StreamPlan plan;
  Status status = job.Prepare(wire, engine, "serial", /*regions=*/server::RegionCaller{}, &plan);
  if (status.ok()) status = engine.Submit(&job);
  if (status.ok()) {
    listener.Wait();
    status = job.status();
  } else {
    job.Fail(status);
  }
  // Parts: the last one is last; a failed frame is one error part; otherwise each
  // instance's vertex ranges follow each other and end at the mesh's vertex count (a
  // packed part holds whole instances: its range once for each).
  std::map<uint32_t, uint64_t> next_vertex;  // by instance
  uint32_t total_vertices = 0;
  bool last = false;
  while (const grpc::ByteBuffer* bytes = job.NextPart(&last)) {
    grpc::ByteBuffer copy(*bytes);  // parsing consumes it
    v1::SkinResponse parsed;
    if (!grpc::SerializationTraits<v1::SkinResponse>::Deserialize(&copy, &parsed).ok()) {
      std::abort();
    }
    const v1::SkinResponse* part = &parsed;
    if (last != part->last()) std::abort();
    if (part->has_error()) {
      if (status.ok() || !last) std::abort();
      continue;
    }
    const uint32_t packed = std::max(part->instance_count(), 1u);
    if (packed > 1 && (!wire.pack_instances() || part->first_vertex() != 0 ||
                       part->vertex_count() != part->total_vertices())) {
      std::abort();
    }
    for (uint32_t k = 0; k < packed; ++k) {
      uint64_t& next = next_vertex[part->instance() + k];
      if (part->first_vertex() != next || part->positions().empty()) std::abort();
      next += part->vertex_count();
    }
    total_vertices = part->total_vertices();
  }
  if (!last) std::abort();
  if (status.ok() && next_vertex.size() != std::max(wire.instances(), 1u)) std::abort();
  for (const auto& [instance, count] : next_vertex) {
    if (count != total_vertices) std::abort();
  }
  job.PartWritten();
  if (job.wire_in_use() || listener.holds.load() != 0) std::abort();
  return 0;
}
