// OpenClEncoder: a frame's encoded output (SkinFrame::encoded, float16 or snorm16) made on
// the device from the skinned floats, so that only the encoded bytes (half of float32's)
// cross back to the host (kernels/encode_output.cl). Shared by an engine's `opencl` and
// `opencl-zerocopy` backends; its program is built (and each kernel run once) on the first
// encoded frame, so runtimes that never see one compile nothing more.
#pragma once

#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <unordered_map>
#include <vector>

#include "backends/opencl/opencl_runtime.h"
#include "skinserve/encoding/vertex_encoding.h"
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
  // The same for a frame whose output is device memory (frame.device, a GPU region, its
  // encoding float16 or snorm16): encoded on the device into the lane's buffers, then copied
  // into the memory at the frame's offsets (WriteDevicePieces); nothing is read back but
  // the flag and snorm16's box, which goes to *frame.device.bounds. A frame the device
  // cannot encode (a box too thin for a float scale) is encoded on the host from the floats
  // read back, and those bytes written into the memory; a value the encoding refuses fails
  // the frame with the host encoder's error, and nothing is written.
  Status EncodeIntoDevice(OpenClLane& lane, const SkinKernelArgs& floats, uint32_t vertex_count,
                          const SkinFrame& frame, ClEvents& kernels, ClEvents& transfers);

 private:
  struct LaneState;
  struct EncodedArray;
  // snorm16's box as the device kernels take it: per axis the centre and 32767 / half-extent.
  struct Snorm16Box {
    float centre[3] = {}, scale[3] = {};
  };
  Status Build();
  Status Warm();
  Result<LaneState*> StateOf(OpenClLane& lane);
  // StateOf for a frame in `encoding`: INVALID_ARGUMENT unless float16 or snorm16.
  Result<LaneState*> StateFor(OpenClLane& lane, VertexEncoding encoding);
  // Reads the flag the encode kernels raise for a value their encoding cannot hold
  // (blocking, in order after them): OK if none was; else `host_encode` names it (the host
  // encoder's error), or INTERNAL if the host encoder took every value after all.
  static Status CheckFlag(OpenClLane& lane, LaneState& state,
                          const std::function<Status()>& host_encode);
  // snorm16: the box of the skinned `positions`, combined from the work-groups' partial rows
  // (read back, blocking); nullopt when a value is not finite.
  Result<std::optional<Bounds>> DeviceBox(OpenClLane& lane, LaneState& state, cl_mem positions,
                                          uint32_t vertex_count, ClEvents& kernels,
                                          ClEvents& transfers);
  // The flag cleared and, for snorm16, the frame's box into *bounds and `box`: false when
  // the device cannot encode the frame (a value not finite, an axis too thin).
  Result<bool> PrepareEncode(OpenClLane& lane, LaneState& state, const SkinKernelArgs& floats,
                             uint32_t vertex_count, VertexEncoding encoding, Bounds* bounds,
                             Snorm16Box* box, ClEvents& kernels, ClEvents& transfers);
  // The frame's encoded arrays: positions, and normals and tangents where it asks for them
  // (host memory: `enc`'s; device memory: frame.device's ranges).
  static std::vector<EncodedArray> EncodedArrays(LaneState& state, const SkinKernelArgs& floats,
                                                 const EncodedOutput& enc, uint32_t vertex_count);
  static std::vector<EncodedArray> DeviceArrays(LaneState& state, const SkinKernelArgs& floats,
                                                const DeviceOutput& device, uint32_t vertex_count);
  // Each array's encode kernel (float16 when `box` is null, else snorm16 with it), writing
  // the caller's memory in place (zero_copy: through `wrapped`) or the lane's buffers.
  Status EnqueueEncodeKernels(OpenClLane& lane, LaneState& state, const Snorm16Box* box,
                              bool zero_copy, std::vector<EncodedArray>& arrays,
                              std::vector<ClBuffer>* wrapped, ClEvents& kernels);
  // The bytes to the host, in order on the compute queue: maps (zero_copy) or reads
  // (through the lane's pinned memory when the runtime stages).
  Status EnqueueReadBack(OpenClLane& lane, bool zero_copy, std::vector<EncodedArray>& arrays,
                         ClEvents& transfers);

  std::shared_ptr<OpenClRuntime> runtime_;
  std::mutex mutex_;
  bool built_ = false;
  Status build_status_;
  cl_program program_ = nullptr;
  std::unordered_map<const OpenClLane*, std::unique_ptr<LaneState>> lanes_;
};

}  // namespace skinserve
