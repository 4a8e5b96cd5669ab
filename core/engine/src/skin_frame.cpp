#include <fmt/format.h>

#include "device_output_checks.h"
#include "skinserve/engine/backend.h"
#include "skinserve/model/palette.h"

namespace skinserve {

bool BackendInfo::Supports(SkinningMethod method) const {
  for (SkinningMethod m : methods) {
    if (m == method) return true;
  }
  return false;
}

bool BackendInfo::WritesEncoding(VertexEncoding encoding) const {
  for (VertexEncoding e : encoded_outputs) {
    if (e == encoding) return true;
  }
  return false;
}

Status CheckMorphSupport(const BackendInfo& info, std::span<const MorphWeight> weights) {
  if (info.morph_targets || !HasActiveMorph(weights)) return Status::Ok();
  return FailedPrecondition(fmt::format(
      "backend '{}' does not apply morph targets; send the frame without morph weights or "
      "choose a backend that does (serial, openmp, sse, sse-openmp, simd, simd-openmp, opencl, "
      "opencl-zerocopy)",
      info.id));
}

Status CheckTangentSupport(const BackendInfo& info, bool tangents_requested) {
  if (info.tangents || !tangents_requested) return Status::Ok();
  return FailedPrecondition(fmt::format(
      "backend '{}' does not skin tangents; ask for the frame without tangents or choose a "
      "backend that does (passthrough, serial, openmp, sse, sse-openmp, simd, simd-openmp, "
      "opencl, opencl-zerocopy)",
      info.id));
}

Status ValidateFramePalette(std::span<const float> palette, SkinningMethod method,
                            uint32_t joint_count) {
  if (Status s = ValidatePalette(palette, joint_count); !s.ok()) return s;
  if (method == SkinningMethod::kDualQuaternion) return ValidateRigidPalette(palette);
  return Status::Ok();
}

Status CheckOutputsAgainstMesh(bool normals, bool tangents, const Mesh& mesh) {
  if (normals && !mesh.has_normals()) {
    return InvalidArgument("normals were requested but the mesh has none");
  }
  if (tangents && !mesh.has_tangents()) {
    return InvalidArgument("tangents were requested but the mesh has none");
  }
  if (tangents && !normals) {
    return InvalidArgument("tangents were requested without normals; ask for normals too");
  }
  return Status::Ok();
}

Status SkinFrame::Validate(const Mesh& mesh) const {
  if (Status s = ValidateFramePalette(palette, method, mesh.joint_count()); !s.ok()) return s;
  if (Status s = ValidateMorphWeights(morph_weights, mesh.morph_target_count()); !s.ok()) return s;
  if (Status s = CheckOutputsAgainstMesh(wants_normals(), wants_tangents(), mesh); !s.ok()) {
    return s;
  }
  if (encoded.active()) return ValidateEncoded(mesh);
  if (device.active()) return ValidateDeviceFrame(*this, mesh);
  const std::size_t expected = 3ull * mesh.vertex_count();
  if (positions.size() != expected) {
    return InvalidArgument(
        fmt::format("positions output holds {} floats; expected 3 * vertex_count = {}",
                    positions.size(), expected));
  }
  if (!normals.empty() && normals.size() != expected) {
    return InvalidArgument(
        fmt::format("normals output holds {} floats; expected 3 * vertex_count = {}",
                    normals.size(), expected));
  }
  if (!tangents.empty() && tangents.size() != 4ull * mesh.vertex_count()) {
    return InvalidArgument(
        fmt::format("tangents output holds {} floats; expected 4 * vertex_count = {}",
                    tangents.size(), 4ull * mesh.vertex_count()));
  }
  return Status::Ok();
}

// Validate() for a frame with encoded output: no float outputs, the encoded ones sized.
Status SkinFrame::ValidateEncoded(const Mesh& mesh) const {
  if (!positions.empty() || !normals.empty() || !tangents.empty()) {
    return InvalidArgument(
        "a frame with encoded output has no float outputs (positions, normals, tangents empty)");
  }
  if (DescribeEncoding(encoded.encoding) == nullptr) {
    return InvalidArgument(
        fmt::format("encoded.encoding {} is unknown", static_cast<int>(encoded.encoding)));
  }
  const uint32_t v = mesh.vertex_count();
  const std::size_t expected = EncodedBytes(encoded.encoding, v);
  if (encoded.positions.size() != expected) {
    return InvalidArgument(fmt::format("encoded positions hold {} bytes; expected {} ({} vertices)",
                                       encoded.positions.size(), expected, v));
  }
  if (!encoded.normals.empty() && encoded.normals.size() != expected) {
    return InvalidArgument(fmt::format("encoded normals hold {} bytes; expected {}",
                                       encoded.normals.size(), expected));
  }
  if (!encoded.tangents.empty() &&
      encoded.tangents.size() != EncodedTangentBytes(encoded.encoding, v)) {
    return InvalidArgument(fmt::format("encoded tangents hold {} bytes; expected {}",
                                       encoded.tangents.size(),
                                       EncodedTangentBytes(encoded.encoding, v)));
  }
  if (QuantizedToBox(encoded.encoding) && encoded.bounds == nullptr) {
    return InvalidArgument(fmt::format("encoded.bounds is null; {} needs the instance's box",
                                       VertexEncodingName(encoded.encoding)));
  }
  return Status::Ok();
}

}  // namespace skinserve
