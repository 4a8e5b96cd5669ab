#include "rpc/engine_messages.h"

#include <fmt/format.h>

namespace skinserve::server {

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

}  // namespace skinserve::server
