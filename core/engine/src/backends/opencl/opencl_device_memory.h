// GPU regions on the `opencl` backend (docs/serving/gpu-regions.md): device memory another
// API allocated and exported as an opaque file descriptor (a Vulkan buffer), imported into
// the runtime's context with cl_khr_external_memory_opaque_fd, and the frames written into
// it: where the frame's offsets are multiples of the device's base-address alignment, the
// kernel writes the imported buffer in place (sub-buffers at those offsets); otherwise it
// runs into the lane's output buffers as for any frame, which are then copied device to
// device into the imported buffer at the frame's offsets. Either way between
// clEnqueueAcquire/ReleaseExternalMemObjectsKHR, and nothing crosses PCIe but the palette.
#pragma once

#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <vector>

#include "backends/opencl/opencl_runtime.h"
#include "skinserve/engine/device_memory.h"

namespace skinserve {

// The extensions an import needs, each named in the FAILED_PRECONDITION of a device that
// lacks it (PoCL has neither), and a UUID that must match the device's.
Result<std::shared_ptr<DeviceMemory>> ImportOpenClDeviceMemory(const OpenClRuntime& runtime,
                                                               const std::string& backend,
                                                               const DeviceMemoryImport& import);

// Plain device memory of the runtime's own context, written by frames as imported memory
// is but without acquire and release: where nothing can be imported (PoCL), the tests run
// the frames' device path on it. Frames go through the lane's buffers and copies unless
// `in_place` (the benchmark's in-place rows and the tests of that path). In place was 3-60x
// slower than the copies on the H200 while each frame made its sub-buffers
// (docs/results/2026-11-29-gpu-regions-in-place-h200); with them kept per range it is
// 1.3-1.5x faster (docs/results/2026-11-29-gpu-sub-buffers-kept-h200).
Result<std::shared_ptr<DeviceMemory>> CreateOpenClDeviceMemory(OpenClRuntime& runtime,
                                                               const std::string& backend,
                                                               uint64_t bytes,
                                                               bool in_place = false);

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

// Frames' pieces into device memory, enqueued on one lane and waited for once: each memory
// is locked (frames on other lanes write it one at a time: an external object is acquired
// by one queue until it is released) and acquired on the lane's queue at its first piece,
// released at Finish, which waits for the queue and then unlocks. Finish runs at
// destruction if it was not called (an error path), so the lane is idle and nothing stays
// acquired.
class DeviceOutputBatch {
 public:
  explicit DeviceOutputBatch(OpenClLane& lane) : lane_(lane) {}
  ~DeviceOutputBatch();
  DeviceOutputBatch(const DeviceOutputBatch&) = delete;
  DeviceOutputBatch& operator=(const DeviceOutputBatch&) = delete;
  // frame.device's memory held by this batch: locked, and acquired on the lane's compute
  // queue (its event to `transfers`) unless the batch holds it already. Before a kernel that
  // writes the memory in place (DirectFloat32Outputs); Enqueue does it itself.
  Status Hold(const SkinFrame& frame, ClEvents& transfers);
  // After the frame's kernels on the lane's compute queue: `pieces` copied (or written)
  // into frame.device's memory on that queue; their events go to `transfers`.
  Status Enqueue(const SkinFrame& frame, std::span<const DeviceOutputPiece> pieces,
                 ClEvents& transfers);
  // Releases what was acquired and waits for the lane's queue: the frames are in the memory.
  Status Finish();

 private:
  struct Held {
    const DeviceMemory* memory;  // an OpenClDeviceMemory
    std::unique_lock<std::mutex> lock;
  };
  OpenClLane& lane_;
  std::vector<Held> held_;
  bool finished_ = false;
};

// One frame's pieces (DeviceOutputBatch), waited for.
Status WriteDevicePieces(OpenClLane& lane, const SkinFrame& frame,
                         std::span<const DeviceOutputPiece> pieces, ClEvents& transfers);

// A float32 frame's outputs as sub-buffers of its device memory at the frame's offsets, for
// the kernel to write in place: no copies, no lane buffers. Empty (none set) when an offset
// is not a multiple of `alignment` (OpenClRuntime::base_address_alignment), or the memory
// is not written in place (plain memory: CreateOpenClDeviceMemory), so the frame goes
// through the lane's buffers and Float32DevicePieces instead.
struct DirectDeviceOutputs {
  ClBuffer positions, normals, tangents;
  bool active() const { return positions.get() != nullptr; }
};
Result<DirectDeviceOutputs> DirectFloat32Outputs(const SkinFrame& frame, uint32_t vertices,
                                                 uint64_t alignment);
// Frames of this process whose outputs DirectFloat32Outputs gave as sub-buffers: for tests,
// which check that an aligned frame was written in place.
uint64_t InPlaceDeviceFrames();

// A frame's float32 outputs (args.out_*) as pieces at frame.device's offsets.
std::vector<DeviceOutputPiece> Float32DevicePieces(const SkinKernelArgs& args, uint32_t vertices,
                                                   const DeviceOutput& device);

}  // namespace skinserve
