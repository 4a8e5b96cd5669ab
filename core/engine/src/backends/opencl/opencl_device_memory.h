// GPU regions on the `opencl` backend (docs/serving/gpu-regions.md): device memory another
// API allocated and exported as an opaque file descriptor (a Vulkan buffer), imported into
// the runtime's context with cl_khr_external_memory_opaque_fd, and the frames written into
// it: the kernel runs into the lane's output buffers as for any frame, then the outputs
// are copied device to device into the imported buffer at the frame's offsets (between
// clEnqueueAcquire/ReleaseExternalMemObjectsKHR), and nothing crosses PCIe but the palette.
#pragma once

#include <memory>
#include <span>
#include <string>

#include "backends/opencl/opencl_runtime.h"
#include "skinserve/engine/device_memory.h"

namespace skinserve {

// The extensions an import needs, each named in the FAILED_PRECONDITION of a device that
// lacks it (PoCL has neither), and a UUID that must match the device's.
Result<std::shared_ptr<DeviceMemory>> ImportOpenClDeviceMemory(const OpenClRuntime& runtime,
                                                               const std::string& backend,
                                                               const DeviceMemoryImport& import);

// Plain device memory of the runtime's own context, written by frames exactly as imported
// memory is but without acquire and release: where nothing can be imported (PoCL), the
// tests run the frames' device path on it.
Result<std::shared_ptr<DeviceMemory>> CreateOpenClDeviceMemory(OpenClRuntime& runtime,
                                                               const std::string& backend,
                                                               uint64_t bytes);

// The cl_mem of OpenCL device memory; null for any other DeviceMemory.
cl_mem OpenClDeviceMemoryBuffer(const DeviceMemory& memory);

// One array of a frame going into device memory at `offset`: `bytes` copied from the
// device buffer `from`, or, when `from` is null, written from `host`.
struct DeviceOutputPiece {
  const char* what;
  cl_mem from;
  const void* host;
  uint64_t offset, bytes;
};

// After the frame's kernels on `lane.compute`: `pieces` copied (or written) into
// frame.device's memory on the same queue, and waited for. The transfers' events go to
// `transfers`.
Status WriteDevicePieces(OpenClLane& lane, const SkinFrame& frame,
                         std::span<const DeviceOutputPiece> pieces, ClEvents& transfers);

// After the frame's kernel on `lane.compute` (into args.out_*): its float32 outputs into
// frame.device's memory at its offsets (WriteDevicePieces).
Status WriteDeviceOutput(OpenClLane& lane, const SkinKernelArgs& args, uint32_t vertices,
                         const SkinFrame& frame, ClEvents& transfers);

}  // namespace skinserve
