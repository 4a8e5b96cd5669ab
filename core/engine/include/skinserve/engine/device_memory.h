// DeviceMemory: memory on a device that another API allocated and a backend imported (a
// GPU region, docs/serving/gpu-regions.md: a Vulkan buffer exported as an opaque file
// descriptor, imported into the `opencl` backend's context). Frames name it with a
// DeviceOutput instead of host arrays; the skinned vertices never leave the device.
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "skinserve/encoding/vertex_encoding.h"
#include "skinserve/model/status.h"

namespace skinserve {

class DeviceMemory {
 public:
  virtual ~DeviceMemory() = default;
  virtual uint64_t byte_size() const = 0;
  // The id of the backend that imported it: only that backend writes into it.
  virtual const std::string& backend() const = 0;
  // Whether an exported semaphore was imported with it (DeviceMemoryImport::semaphore_fd).
  virtual bool signals_semaphore() const { return false; }
  // Signals that semaphore once, for a frame whose writes into the memory are done (all its
  // instances); submitted to the device before it returns. OK and nothing without one.
  // The server calls it once per answered frame (docs/serving/gpu-regions.md#semaphore).
  virtual Status SignalFrameWritten() const { return Status::Ok(); }
};

// What to import: an exported allocation's opaque file descriptor, its size and the
// device it lives on (the 16-byte UUID that Vulkan and OpenCL both report).
struct DeviceMemoryImport {
  int fd = -1;  // on success the importer owns it; on failure the caller still does
  uint64_t byte_size = 0;
  std::array<uint8_t, 16> device_uuid = {};
  // An exported binary semaphore's opaque fd (-1: none) that SignalFrameWritten signals;
  // owned like `fd`.
  int semaphore_fd = -1;
};

// A frame's output in imported device memory: byte offsets of positions, normals and
// tangents (x y z per vertex; tangents x y z w) in `encoding`: float32, or one the
// backend writes itself (BackendInfo::encoded_outputs), each array EncodedBytes
// (EncodedTangentBytes) long, exactly the bytes the host encoders would make. In an engine
// SkinRequest the offsets are instance 0's and instance i's follow at i * instance_bytes
// (i * tangent_instance_bytes for tangents); in a backend's SkinFrame they are the
// instance's own.
struct DeviceOutput {
  const DeviceMemory* memory = nullptr;
  uint64_t positions_offset = 0;
  uint64_t normals_offset = 0;
  uint64_t tangents_offset = 0;
  uint64_t instance_bytes = 0;          // SkinRequest only
  uint64_t tangent_instance_bytes = 0;  // SkinRequest only
  bool normals = false;
  bool tangents = false;
  VertexEncoding encoding = VertexEncoding::kFloat32;
  // Boxed encodings (snorm16): where each instance's box goes, the one its positions were
  // quantized to (instance i's at bounds[i] in a SkinRequest; the instance's own in a
  // SkinFrame); else unused.
  Bounds* bounds = nullptr;
  bool active() const { return memory != nullptr; }
};

}  // namespace skinserve
