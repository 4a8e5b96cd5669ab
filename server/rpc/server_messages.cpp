#include "rpc/server_messages.h"

namespace skinserve::server {
namespace {

void ToWire(const DurationHistogram& h, v1::DurationHistogram* wire) {
  uint64_t cumulative = 0;
  for (std::size_t i = 0; i < DurationHistogram::kBounds.size(); ++i) {
    cumulative += h.buckets[i];
    wire->add_upper_bounds(DurationHistogram::kBounds[i]);
    wire->add_bucket_counts(cumulative);
  }
  wire->set_count(h.count);
  wire->set_sum_seconds(h.sum_seconds);
}

}  // namespace

v1::MeshInfo ToWire(const MeshInfo& info) {
  v1::MeshInfo wire;
  wire.set_mesh_id(info.id);
  wire.set_vertex_count(info.vertex_count);
  wire.set_influences(info.influences);
  wire.set_joint_count(info.joint_count);
  wire.set_has_normals(info.has_normals);
  wire.set_bytes(info.bytes);
  wire.set_normalized_vertices(info.normalized_vertices);
  wire.set_already_stored(info.already_stored);
  wire.set_morph_target_count(info.morph_target_count);
  wire.set_rest_encoding(ToWire(info.rest_encoding));
  wire.set_has_tangents(info.has_tangents);
  return wire;
}

v1::BackendInfo ToWire(const BackendInfo& info) {
  v1::BackendInfo wire;
  wire.set_id(info.id);
  wire.set_description(info.description);
  wire.set_available(info.available);
  wire.set_unavailable_reason(info.unavailable_reason);
  wire.set_device(info.device);
  wire.set_simd_width(info.simd_width);
  wire.set_simd_target(info.simd_target);
  wire.set_threads(info.threads);
  for (SkinningMethod method : info.methods) wire.add_methods(ToWire(method));
  wire.set_morph_targets(info.morph_targets);
  wire.set_quantized_rest(info.quantized_rest);
  wire.set_tangents(info.tangents);
  for (VertexEncoding encoding : info.encoded_outputs) wire.add_encoded_outputs(ToWire(encoding));
  return wire;
}

v1::ServerStats ToWire(const ServerSnapshot& s) {
  v1::ServerStats wire;
  wire.set_version(s.version);
  wire.set_serving(s.serving);
  const EngineStats& e = s.engine;
  for (const BackendStats& b : e.backends) {
    v1::BackendStats* out = wire.add_backends();
    out->set_id(b.id);
    out->set_frames(b.frames);
    out->set_vertices(b.vertices);
    out->set_errors(b.errors);
    out->set_compute_ns_total(b.compute_ns_total);
    if (auto f = s.frames.find(b.id); f != s.frames.end()) {
      for (const auto& [code, n] : f->second.errors_by_code)
        (*out->mutable_errors_by_code())[code] = n;
      ToWire(f->second.queue, out->mutable_queue());
      ToWire(f->second.compute, out->mutable_compute());
      ToWire(f->second.encode, out->mutable_encode());
      ToWire(f->second.server, out->mutable_server());
    }
  }
  wire.set_queue_depth(e.queue_depth);
  wire.set_queue_capacity(e.queue_capacity);
  wire.set_compute_threads(e.compute_threads);
  wire.set_peak_busy_threads(e.peak_busy_threads);
  wire.set_inline_frames(e.inline_frames);
  wire.set_frame_plans_built(e.plans_built);
  wire.set_frame_plans_reused(e.plans_reused);
  wire.set_ticks(s.ticks.ticks);
  wire.set_tick_characters(s.ticks.characters);
  wire.set_meshes(e.meshes);
  wire.set_mesh_bytes(e.mesh_bytes);
  wire.set_mesh_budget_bytes(e.mesh_budget_bytes);
  wire.set_evictions(e.evictions);
  wire.set_rejected_queue_full(e.rejected_queue_full);
  wire.set_open_streams(s.open_streams);
  wire.set_ended_streams_idle(s.streams_ended_idle);
  wire.set_frame_socket_connections(s.frame_socket.connections);
  wire.set_frame_socket_refused(s.frame_socket.refused);
  wire.set_frame_socket_requests(s.frame_socket.requests);
  wire.set_inflight_budget_bytes(s.inflight.budget_bytes);
  wire.set_inflight_bytes(s.inflight.bytes);
  wire.set_rejected_inflight_budget(s.inflight.refused);
  if (s.shared_memory) {
    wire.set_regions(s.regions.regions);
    wire.set_region_bytes(s.regions.mapped_bytes);
    wire.set_region_budget_bytes(s.regions.budget_bytes);
    wire.set_region_frames(s.regions.frames);
    wire.set_rejected_regions(s.regions.rejected);
  }
  const UploadStats& u = s.uploads;
  wire.set_upload_budget_bytes(u.budget_bytes);
  wire.set_upload_bytes(u.bytes);
  wire.set_open_uploads(u.open);
  wire.set_rejected_uploads_max_uploads(u.refused_max_uploads);
  wire.set_rejected_uploads_per_connection(u.refused_per_connection);
  wire.set_rejected_uploads_budget(u.refused_budget);
  wire.set_cancelled_uploads_idle(u.cancelled_idle);
  wire.set_cancelled_uploads_deadline(u.cancelled_deadline);
  wire.set_skeletons(s.animations.skeletons);
  wire.set_clips(s.animations.clips);
  wire.set_clip_bytes(s.animations.bytes);
  wire.set_clip_budget_bytes(s.animations.budget_bytes);
  return wire;
}

void ToWire(const RegionInfo& info, v1::RegionInfo* wire) {
  wire->set_name(info.name);
  wire->set_key(info.key);
  wire->set_byte_size(info.byte_size);
  wire->set_frames_written(info.frames_written);
  wire->set_idle_seconds(info.idle_seconds);
}

void ToWire(const animation::SkeletonInfo& info, v1::SkeletonInfo* wire) {
  wire->set_skeleton_id(info.id);
  wire->set_joint_count(info.joint_count);
  wire->set_palette_size(info.palette_size);
  wire->set_bytes(info.bytes);
  wire->set_already_stored(info.already_stored);
}

void ToWire(const animation::ClipInfo& info, v1::ClipInfo* wire) {
  wire->set_clip_id(info.id);
  wire->set_name(info.name);
  wire->set_duration(info.duration);
  wire->set_joint_count(info.joint_count);
  wire->set_weight_count(info.weight_count);
  wire->set_tracks(info.tracks);
  wire->set_bytes(info.bytes);
  wire->set_raw_bytes(info.raw_bytes);
  wire->set_already_stored(info.already_stored);
  wire->set_max_error_mm(info.max_error_mm);
}

}  // namespace skinserve::server
