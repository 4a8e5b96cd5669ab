// A StreamSkin/Skin frame from raw wire bytes: the input is one SkinRequest message. It
// goes the server's way: FrameJob::Prepare (mesh lookup, backend, palette bytes decoded),
// the engine (palette validated against the mesh's joints, skinned on `serial`), then the
// answer cut into response parts, which must cover the mesh's vertices exactly once.
// mesh_id "m" stands for the mesh stored at start-up, so inputs can reach the skinning.
#include <cstdint>
#include <cstdlib>
#include <map>

#include "frame_job.h"
#include "fuzz_engine.h"
#include "skinserve/core/synthetic.h"

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

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  Engine& engine = fuzz::FuzzEngine();
  v1::SkinRequest wire;
  if (!wire.ParseFromArray(data, static_cast<int>(size))) return 0;
  if (wire.mesh_id() == "m") wire.set_mesh_id(StoredMeshId());
  server::FrameJob job;
  SkinRequest request;
  Status status = job.Prepare(wire, engine, "serial", &request);
  if (status.ok()) status = engine.SkinBlocking(std::move(request));
  job.Complete(status, {});
  // Parts: the last one is last; a failed frame is one error part; otherwise each
  // instance's vertex ranges follow each other and end at the mesh's vertex count.
  v1::SkinResponse part;
  std::map<uint32_t, uint64_t> next_vertex;  // by instance
  bool last = false;
  while (job.NextPart(&part)) {
    if (last) std::abort();
    last = part.last();
    if (part.has_error()) {
      if (status.ok() || !last) std::abort();
      continue;
    }
    uint64_t& next = next_vertex[part.instance()];
    if (part.first_vertex() != next || part.positions().empty()) std::abort();
    next += part.vertex_count();
  }
  if (!last) std::abort();
  for (const auto& [instance, count] : next_vertex) {
    if (count != part.total_vertices()) std::abort();
  }
  return 0;
}
