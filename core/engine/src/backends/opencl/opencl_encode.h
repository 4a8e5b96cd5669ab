// OpenClEncoder: a frame's encoded output (SkinFrame::encoded, float16 or snorm16) made on
// the device from the skinned floats, so that only the encoded bytes (half of float32's)
// cross back to the host (kernels/encode_output.cl). Shared by an engine's `opencl` and
// `opencl-zerocopy` backends; its program is built (and each kernel run once) on the first
// encoded frame, so runtimes that never see one compile nothing more.
#pragma once

#include <memory>
#include <mutex>
#include <unordered_map>
#include <vector>

#include "backends/opencl/opencl_runtime.h"
#include "skinserve/engine/backend.h"

namespace skinserve {

// The encodings the OpenCL backends write themselves (BackendInfo::encoded_outputs).
std::vector<VertexEncoding> OpenClEncodedOutputs();

class OpenClEncoder {
 public:
  explicit OpenClEncoder(std::shared_ptr<OpenClRuntime> runtime);
  ~OpenClEncoder();
  OpenClEncoder(const OpenClEncoder&) = delete;
  OpenClEncoder& operator=(const OpenClEncoder&) = delete;

  // After the frame's skinning kernels, enqueued on lane.compute, write its floats to
  // `floats` (out_positions, out_normals, out_tangents as the frame asks): encodes them on
  // the same queue and writes the bytes into frame.encoded (and, snorm16, the box into
  // *frame.encoded.bounds). zero_copy: the kernels write the caller's memory through
  // CL_MEM_USE_HOST_PTR buffers; else device buffers read back (through the lane's pinned
  // memory when the runtime stages). snorm16 reads the box's per-work-group partials back
  // first (a few KiB) and encodes with the box the host combined from them. Blocks until
  // the bytes are there. A value the encoding refuses: the floats are read back and the host
  // encoder's error returned (INVALID_ARGUMENT naming the vertex).
  Status Encode(OpenClLane& lane, const SkinKernelArgs& floats, uint32_t vertex_count,
                const SkinFrame& frame, bool zero_copy, ClEvents& kernels, ClEvents& transfers);

 private:
  struct LaneState;
  Status Build();
  Status Warm();
  Result<LaneState*> StateOf(OpenClLane& lane);

  std::shared_ptr<OpenClRuntime> runtime_;
  std::mutex mutex_;
  bool built_ = false;
  Status build_status_;
  cl_program program_ = nullptr;
  std::unordered_map<const OpenClLane*, std::unique_ptr<LaneState>> lanes_;
};

}  // namespace skinserve
