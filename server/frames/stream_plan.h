// StreamPlan: a stream's frame plan, made once and reused while its frames' settings stay
// the same. A stream's frames almost never change mesh, backend, method, encoding, batch
// size, outputs or region, so what those fix is checked and computed once: the engine's
// plan (backend, method, mesh looked up, batch limits: Engine::Plan), the outputs the mesh
// can give, the sizes of every buffer and part (FrameLayout) and where in the region the
// frame goes. A frame whose settings match the plan's key reuses it (Engine::Reuse: no
// lookup, no lock) and checks only what can change from frame to frame: its palette, its
// morph weights, that its mesh and region still stand, and its range against the region.
// The offset into the region is no such setting: a client that double-buffers a region
// changes it every frame. A frame whose settings differ rebuilds the plan; a failed build
// keeps nothing, so the next frame builds again. The plan holds the mesh and the region
// weakly (KeptPlan, RegionHandle): a mesh deleted or a region unregistered is seen by the
// next frame, which is then planned afresh and answered with the lookup's status
// (NOT_FOUND ...).
// Used under its owner's lock (a stream's reactor; a tick's character slot).
#pragma once

#include <cstdint>
#include <string>

#include "shm/region_handle.h"
#include "skinserve/encoding/vertex_encoding.h"
#include "skinserve/engine/engine.h"
#include "skinserve/v1/skinning.pb.h"

namespace skinserve::server {

// The most vertex data one answer part carries (so no message needs more than gRPC's
// default 4 MiB).
inline constexpr std::size_t kMaxPartPayloadBytes = 1 << 20;

// What a frame's plan fixes of its buffers and its answer (FrameJob's layout).
struct FrameLayout {
  uint32_t vertices = 0;  // per instance: the mesh's
  uint32_t instances = 1;
  VertexEncoding encoding = VertexEncoding::kFloat32;
  bool want_normals = false;
  bool want_tangents = false;
  bool boxed = false;           // each instance's box travels with it (snorm16)
  bool device_encoded = false;  // the backend writes the encoding (BackendInfo.encoded_outputs)
  bool box_scratch = false;     // ...snorm16 on the host: the job's float buffer is its scratch
  bool scratch = false;         // skinned into the compute thread's scratch, then encoded
  bool early = false;           // SkinRequest.early_parts, when it has parts to send early
  uint64_t values = 0;          // 3 * vertices * instances
  uint64_t tangent_values = 0;  // 4 * vertices * instances with tangents, else 0
  std::size_t payload = 0;      // the positions' encoded bytes (the normals' too)
  uint64_t floats_kept = 0;     // bytes of float buffers the job keeps for the frame
  // The answer's parts: at most kMaxPartPayloadBytes of vertex data each.
  uint32_t vertices_per_part = 1;
  std::size_t parts_per_instance = 1;
  std::size_t part_count = 0;
  uint32_t instances_per_part = 1;  // > 1: packed parts (SkinRequest.pack_instances)
  // The wire buffer: positions from 0, normals, tangents, then each part's header room.
  std::size_t header_room = 0, normals_offset = 0, tangents_offset = 0, headers_offset = 0,
              wire_used = 0;
  // SkinRequest.output: the frame goes into a region (its answer one header). Where in it
  // is each frame's own (FrameJob::PlaceInRegion): the offset is no key, since a client
  // double-buffering a region alternates it every frame.
  bool in_region = false;
};

class StreamPlan {
 public:
  // Whether `request`, its backend `backend` (the server's default applied), has the
  // settings this plan was built for: the key.
  bool Matches(const v1::SkinRequest& request, const std::string& backend) const;
  // Plans `job` (fills its request's mesh_id, backend, method and instances) for
  // `request`: from this plan when the key matches and the mesh is still stored, else
  // built anew and kept. Errors: the engine's (Engine::Plan), the request's method or
  // encoding unknown, outputs the mesh cannot give (the output offset is each frame's:
  // FrameJob::PlaceInRegion).
  Status PlanFrame(const v1::SkinRequest& request, const std::string& backend, Engine& engine,
                   SkinJob* job);
  // The layout of the frame PlanFrame planned last.
  const FrameLayout& layout() const { return layout_; }
  // The stream's hold on the region its frames write into.
  RegionHandle* region() { return &region_; }
  // Builds so far (the first frame's, and after every change): for tests and metrics.
  uint64_t builds() const { return builds_; }
  void Reset();

 private:
  Status Build(const v1::SkinRequest& request, const std::string& backend, Engine& engine,
               SkinJob* job);
  void SetKey(const v1::SkinRequest& request, const std::string& backend);
  // The request's engine fields, as the plan has them.
  void FillJob(SkinJob* job) const;

  bool built_ = false;
  // The key: every request field that the plan depends on.
  std::string mesh_id_, backend_;
  int method_ = 0, encoding_ = 0;  // the wire's values
  uint32_t instances_ = 1;
  bool want_normals_ = false, want_tangents_ = false, pack_instances_ = false, early_parts_ = false,
       has_output_ = false;
  std::string output_region_;

  SkinningMethod method_value_ = SkinningMethod::kLinear;
  KeptPlan kept_;
  FrameLayout layout_;
  RegionHandle region_;
  uint64_t builds_ = 0;
};

// The layout of `request`'s frame on the engine's plan `plan`: the outputs the mesh and
// backend can give (want_normals, want_tangents) and every size. INVALID_ARGUMENT naming
// the field.
Status LayOutFrame(const v1::SkinRequest& request, const FramePlan& plan, FrameLayout* layout);

}  // namespace skinserve::server
