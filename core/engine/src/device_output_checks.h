// The engine's checks of frames whose output is in imported device memory (DeviceOutput,
// skinserve/engine/device_memory.h), and each instance's part of such a request.
#pragma once

#include <cstdint>

#include "skinserve/engine/backend.h"
#include "skinserve/engine/engine.h"

namespace skinserve {

// Whether [offset, offset + bytes) lies inside `size` bytes (no wrap-around).
bool RangeInside(uint64_t offset, uint64_t bytes, uint64_t size);

// One instance's frame: no host outputs; normals and tangents as the mesh allows.
Status ValidateDeviceFrame(const SkinFrame& frame, const Mesh& mesh);

// A request with device output (request.device active): no host, encoded or scratch
// outputs; the memory imported by the frame's backend (`info`) and an encoding it writes
// itself, else FAILED_PRECONDITION; snorm16 with somewhere for the boxes and every
// instance's arrays (in the encoding's bytes) inside the memory, else INVALID_ARGUMENT
// naming the field or the range.
Status CheckDeviceRequest(const SkinRequest& request, const Mesh& mesh, uint32_t instances,
                          const BackendInfo& info);

// Instance `i`'s DeviceOutput of `request` (inactive when the request's is).
DeviceOutput InstanceDeviceOutput(const SkinRequest& request, uint32_t i);

}  // namespace skinserve
