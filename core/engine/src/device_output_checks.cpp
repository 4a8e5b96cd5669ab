#include "device_output_checks.h"

#include <fmt/format.h>

namespace skinserve {
bool RangeInside(uint64_t offset, uint64_t bytes, uint64_t size) {
  return bytes <= size && offset <= size - bytes;
}

Result<std::shared_ptr<DeviceMemory>> Backend::ImportDeviceMemory(const DeviceMemoryImport&) {
  return FailedPrecondition(fmt::format(
      "backend '{}' cannot write into GPU memory: only 'opencl' imports it, on a device whose "
      "OpenCL offers cl_khr_external_memory_opaque_fd",
      info().id));
}

void Backend::SkinFrames(std::span<const PreparedMesh* const> prepared,
                         std::span<const SkinFrame> frames, std::span<Status> statuses) {
  for (std::size_t i = 0; i < frames.size(); ++i) statuses[i] = Skin(*prepared[i], frames[i]);
}

Status ValidateDeviceFrame(const SkinFrame& frame, const Mesh& mesh) {
  if (!frame.positions.empty() || !frame.normals.empty() || !frame.tangents.empty() ||
      frame.encoded.active()) {
    return InvalidArgument(
        "a frame with device output has no host outputs (positions, normals, tangents, encoded)");
  }
  if (frame.device.normals && !mesh.has_normals()) {
    return InvalidArgument("normals were requested but the mesh has none");
  }
  if (frame.device.tangents && (!frame.device.normals || !mesh.has_tangents())) {
    return InvalidArgument(frame.device.normals
                               ? "tangents were requested but the mesh has none"
                               : "tangents were requested without normals; ask for normals too");
  }
  return Status::Ok();
}

Status CheckDeviceRequest(const SkinRequest& request, const Mesh& mesh, uint32_t instances,
                          const BackendInfo& info) {
  const DeviceOutput& d = request.device;
  if (!request.positions.empty() || !request.normals.empty() || !request.tangents.empty() ||
      request.encoded.active() || request.skin_into_scratch) {
    return InvalidArgument(
        "a frame with device output has no host outputs (positions, normals, tangents, "
        "encoded, skin_into_scratch)");
  }
  if (d.memory->backend() != info.id) {
    return FailedPrecondition(
        fmt::format("the frame's device memory was imported by backend '{}', not by '{}': only "
                    "the backend that imported it writes into it",
                    d.memory->backend(), info.id));
  }
  if (d.encoding != VertexEncoding::kFloat32 && !info.WritesEncoding(d.encoding)) {
    return FailedPrecondition(fmt::format(
        "backend '{}' does not write {} itself, and device output is never read back to be "
        "encoded on the host",
        info.id, VertexEncodingName(d.encoding)));
  }
  if (QuantizedToBox(d.encoding) && d.bounds == nullptr) {
    return InvalidArgument(fmt::format("device.bounds is null; {} needs each instance's box",
                                       VertexEncodingName(d.encoding)));
  }
  const uint64_t size = d.memory->byte_size();
  const uint64_t array_bytes = EncodedBytes(d.encoding, mesh.vertex_count());
  const uint64_t tangent_bytes = EncodedTangentBytes(d.encoding, mesh.vertex_count());
  if (d.instance_bytes < array_bytes || (d.tangents && d.tangent_instance_bytes < tangent_bytes)) {
    return InvalidArgument(fmt::format(
        "device output strides ({} / {} bytes) are below one instance's arrays ({} / {} bytes)",
        d.instance_bytes, d.tangent_instance_bytes, array_bytes, tangent_bytes));
  }
  for (uint32_t i = 0; i < instances; ++i) {
    const DeviceOutput out = InstanceDeviceOutput(request, i);
    const bool fits = RangeInside(out.positions_offset, array_bytes, size) &&
                      (!d.normals || RangeInside(out.normals_offset, array_bytes, size)) &&
                      (!d.tangents || RangeInside(out.tangents_offset, tangent_bytes, size));
    if (!fits) {
      return InvalidArgument(fmt::format(
          "instance {}'s output (positions at {}, normals at {}, tangents at {}) does not fit "
          "the device memory's {} bytes",
          i, out.positions_offset, out.normals_offset, out.tangents_offset, size));
    }
  }
  return Status::Ok();
}

DeviceOutput InstanceDeviceOutput(const SkinRequest& request, uint32_t i) {
  DeviceOutput out = request.device;
  if (!out.active()) return out;
  out.positions_offset += i * out.instance_bytes;
  out.normals_offset += i * out.instance_bytes;
  out.tangents_offset += i * out.tangent_instance_bytes;
  if (out.bounds != nullptr) out.bounds += i;
  return out;
}

}  // namespace skinserve
