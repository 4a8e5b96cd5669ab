#include "frames/stream_plan.h"

#include <fmt/format.h>

#include <algorithm>

#include "rpc/server_messages.h"

namespace skinserve::server {
namespace {

// Room for one part's header: the fields besides the vertex data take at most ~160
// bytes (varints, the timings, a snorm16 box), and the two tags with their lengths 12;
// a packed part adds each instance's box (32 bytes with its tag and length).
constexpr std::size_t kHeaderRoom = 256;
constexpr std::size_t kBoundsRoom = 40;

constexpr std::size_t RoundUp(std::size_t n) {
  return (n + kBufferAlignment - 1) / kBufferAlignment * kBufferAlignment;
}

// The outputs asked for against what the mesh has (the wire's fields named).
Status CheckWantedOutputs(const v1::SkinRequest& request, const FramePlan& plan) {
  if (request.want_normals() && !plan.has_normals) {
    return InvalidArgument("want_normals is set but mesh " + request.mesh_id() + " has no normals");
  }
  if (!request.want_tangents()) return Status::Ok();
  if (!request.want_normals()) {
    return InvalidArgument("want_tangents is set without want_normals; ask for normals too");
  }
  if (!plan.has_tangents) {
    return InvalidArgument("want_tangents is set but mesh " + request.mesh_id() +
                           " has no tangents (MeshHeader.has_tangents)");
  }
  return Status::Ok();
}

// The answer's parts over the wire buffer: how many, how large, where their headers go.
void LayOutParts(bool pack_instances, FrameLayout* l) {
  const std::size_t value_bytes = EncodedBytesPerValue(l->encoding);
  const std::size_t vertex_bytes =
      ((l->want_normals ? 6 : 3) + (l->want_tangents ? kValuesPerTangent : 0)) * value_bytes;
  l->vertices_per_part =
      static_cast<uint32_t>(std::max<std::size_t>(1, kMaxPartPayloadBytes / vertex_bytes));
  l->parts_per_instance =
      std::max<std::size_t>(1, (l->vertices + l->vertices_per_part - 1) / l->vertices_per_part);
  l->part_count = l->parts_per_instance * l->instances;
  // Packed: as many whole instances per part as fit in 1 MiB.
  l->instances_per_part = 1;
  if (pack_instances && l->parts_per_instance == 1 && l->vertices > 0) {
    l->instances_per_part = static_cast<uint32_t>(
        std::min<std::size_t>(l->instances, kMaxPartPayloadBytes / (vertex_bytes * l->vertices)));
    l->instances_per_part = std::max<uint32_t>(l->instances_per_part, 1);
    l->part_count = (l->instances + l->instances_per_part - 1) / l->instances_per_part;
  }
  l->header_room =
      kHeaderRoom +
      (l->boxed && l->instances_per_part > 1 ? kBoundsRoom * l->instances_per_part : 0);
  l->payload = l->values * value_bytes;
  l->normals_offset = RoundUp(l->payload);  // the positions start the buffer
  l->tangents_offset = l->normals_offset + (l->want_normals ? RoundUp(l->payload) : 0);
  l->headers_offset =
      l->tangents_offset + RoundUp(static_cast<std::size_t>(l->tangent_values) * value_bytes);
}

// A frame into a region: the vertices go there, the wire carries one header. Where in the
// region is each frame's own (FrameJob::PlaceInRegion).
void LayOutRegion(const v1::OutputRegion& output, FrameLayout* l) {
  l->in_region = true;
  l->part_count = 1;
  l->instances_per_part = 1;
  l->header_room =
      kHeaderRoom + output.region().size() + (l->boxed ? kBoundsRoom * l->instances : 0);
  l->normals_offset = l->tangents_offset = l->headers_offset = 0;
}

// Where the skinned floats go: straight into the output (float32, or a backend that writes
// the encoding), the compute thread's scratch, or the job's float buffers.
void LayOutFloats(const FramePlan& plan, FrameLayout* l) {
  const bool float32 = l->encoding == VertexEncoding::kFloat32;
  // A backend that writes this encoding itself (on its device: only the encoded bytes come
  // back) skins straight into the wire buffer or the region, and sends the boxes it found.
  l->device_encoded = !float32 && plan.BackendWrites(l->encoding);
  // snorm16 written by a host backend (simd): it keeps the positions as floats until it has
  // their box, in the job's buffer, so that they are counted.
  l->box_scratch = l->device_encoded && l->boxed && plan.backend_box_scratch;
  // Encoded instance by instance: skinned into the compute thread's scratch, kept in its
  // core's cache, unless an instance is too large for it. Tangents are never skinned into
  // scratch (the engine's rule): such frames keep floats.
  l->scratch =
      !float32 && !l->device_encoded && !l->want_tangents &&
      ScratchFloatsPerInstance(l->vertices, l->want_normals) <= kMaxScratchFloatsPerInstance;
  l->floats_kept = 0;
  if (l->box_scratch) {
    l->floats_kept = l->values * sizeof(float);
  } else if (!float32 && !l->scratch && !l->device_encoded) {
    l->floats_kept = ((l->want_normals ? 2 : 1) * l->values + l->tangent_values) * sizeof(float);
  }
}

}  // namespace

Status LayOutFrame(const v1::SkinRequest& request, const FramePlan& plan, FrameLayout* layout) {
  FrameLayout& l = *layout;
  l = {};
  if (Status s = CheckWantedOutputs(request, plan); !s.ok()) return s;
  Result<VertexEncoding> encoding = FromWire(request.encoding());
  if (!encoding.ok()) return encoding.status();
  l.encoding = *encoding;
  l.boxed = QuantizedToBox(l.encoding);
  l.vertices = plan.vertex_count;
  l.instances = plan.instances;
  l.want_normals = request.want_normals();
  l.want_tangents = request.want_tangents();
  l.values = 3ull * l.vertices * l.instances;
  l.tangent_values = l.want_tangents ? uint64_t{kValuesPerTangent} * l.vertices * l.instances : 0;
  LayOutParts(request.pack_instances(), &l);
  if (request.has_output()) LayOutRegion(request.output(), &l);
  l.wire_used = l.headers_offset + l.part_count * l.header_room;
  l.early = request.early_parts() && !l.in_region && l.part_count > 1 && l.instances > 1;
  LayOutFloats(plan, &l);
  return Status::Ok();
}

bool StreamPlan::Matches(const v1::SkinRequest& r, const std::string& backend) const {
  return built_ && r.mesh_id() == mesh_id_ && backend == backend_ && r.method() == method_ &&
         r.encoding() == encoding_ && std::max<uint32_t>(r.instances(), 1) == instances_ &&
         r.want_normals() == want_normals_ && r.want_tangents() == want_tangents_ &&
         r.pack_instances() == pack_instances_ && r.early_parts() == early_parts_ &&
         r.has_output() == has_output_ && (!has_output_ || r.output().region() == output_region_);
}

void StreamPlan::SetKey(const v1::SkinRequest& r, const std::string& backend) {
  mesh_id_.assign(r.mesh_id());
  backend_.assign(backend);
  method_ = r.method();
  encoding_ = r.encoding();
  instances_ = std::max<uint32_t>(r.instances(), 1);
  want_normals_ = r.want_normals();
  want_tangents_ = r.want_tangents();
  pack_instances_ = r.pack_instances();
  early_parts_ = r.early_parts();
  has_output_ = r.has_output();
  output_region_.assign(has_output_ ? r.output().region() : std::string());
}

void StreamPlan::FillJob(SkinJob* job) const {
  job->request.mesh_id.assign(mesh_id_);
  job->request.backend.assign(backend_);
  job->request.method = method_value_;
  job->request.instances = instances_;
}

Status StreamPlan::PlanFrame(const v1::SkinRequest& request, const std::string& backend,
                             Engine& engine, SkinJob* job) {
  if (Matches(request, backend)) {
    FillJob(job);
    if (engine.Reuse(kept_, job)) return Status::Ok();
  }
  // New settings, or the mesh is gone: planned afresh (a mesh uploaded again is found).
  Status s = Build(request, backend, engine, job);
  if (!s.ok()) Reset();
  return s;
}

Status StreamPlan::Build(const v1::SkinRequest& request, const std::string& backend, Engine& engine,
                         SkinJob* job) {
  Reset();
  ++builds_;
  Result<SkinningMethod> method = FromWire(request.method());
  if (!method.ok()) return method.status();
  SetKey(request, backend);
  method_value_ = *method;
  FillJob(job);
  if (Status s = engine.Plan(job); !s.ok()) return s;
  if (Status s = LayOutFrame(request, job->plan(), &layout_); !s.ok()) return s;
  engine.Keep(*job, &kept_);
  built_ = true;
  return Status::Ok();
}

void StreamPlan::Reset() {
  built_ = false;
  kept_.Reset();
}

}  // namespace skinserve::server
