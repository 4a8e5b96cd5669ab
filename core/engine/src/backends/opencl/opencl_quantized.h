// The OpenCL backends' side of a quantized rest stream (skinserve/model/quantized_rest.h,
// kernels/quantized_skinning.cl): such a mesh lives on the device as its integers only, and
// its frames run the qskin_* kernels with the frame's palette folded with the mesh's box
// (quantized_palette.h). Linear blending only, as `simd`.
#pragma once

#include <CL/cl.h>

#include <cstdint>
#include <map>
#include <mutex>
#include <span>
#include <string>
#include <tuple>

#include "backends/opencl/opencl_runtime.h"
#include "skinserve/engine/backend.h"

namespace skinserve {

// The device buffers of a quantized mesh: uint16 positions, snorm16 normals and tangents
// (when the mesh has them), its joints and B - 1 weights at their stored widths. `flags` adds
// CL_MEM_COPY_HOST_PTR (`opencl`) or CL_MEM_USE_HOST_PTR (`opencl-zerocopy`) to read-only.
// B = 1 stores no weights: `weights` is then a 4-byte placeholder the kernels never read.
struct QuantizedDeviceMesh {
  ClBuffer positions, normals, tangents, joints, weights;
};
Result<QuantizedDeviceMesh> CreateQuantizedDeviceMesh(OpenClRuntime& runtime, const Mesh& mesh,
                                                      cl_mem_flags flags);

// A quantized mesh's device buffers (CreateQuantizedDeviceMesh) moved into a prepared mesh's
// fields, after its kernels ran once (OpenClQuantizedKernels::Warm).
Status PrepareQuantizedMesh(OpenClRuntime& runtime, const Mesh& mesh, cl_mem_flags flags,
                            ClBuffer* positions, ClBuffer* normals, ClBuffer* tangents,
                            ClBuffer* joints, ClBuffer* weights);

// FAILED_PRECONDITION for a method other than linear blending on a quantized mesh (the
// words `simd` uses), else OK.
Status CheckQuantizedMethod(const std::string& backend_id, const Mesh& mesh, SkinningMethod method);

// The frame's palette folded with the mesh's box, 12 floats per joint, in this thread's
// buffer (valid until the thread's next call).
std::span<const float> FoldedQuantizedPalette(std::span<const float> palette,
                                              const QuantizedRest& rest);

// The qskin_* programs of one runtime (one per joint and weight width, built on the first
// mesh that needs it) and their kernel objects, one set per lane. Thread-safe.
class OpenClQuantizedKernels {
 public:
  // `build_options`: the runtime's (work-item shape, local palette, tiles).
  OpenClQuantizedKernels(cl_context context, cl_device_id device, std::string build_options,
                         int local_tiles);
  ~OpenClQuantizedKernels();
  OpenClQuantizedKernels(const OpenClQuantizedKernels&) = delete;
  OpenClQuantizedKernels& operator=(const OpenClQuantizedKernels&) = delete;

  // Builds the mesh's program if needed and runs the kernels its frames may take once,
  // so that its first frame compiles nothing (PoCL compiles a kernel on first launch).
  Status Warm(OpenClRuntime& runtime, const Mesh& mesh, const QuantizedDeviceMesh& device_mesh);

  // EnqueueSkin for a quantized mesh: args.palette holds the folded palette, args.joints,
  // weights, positions, normals and tangents the QuantizedDeviceMesh's buffers.
  Status Enqueue(OpenClLane& lane, const Mesh& mesh, const SkinKernelArgs& args, uint32_t first,
                 uint32_t end, bool local, cl_event* event);

 private:
  // [16-bit joints][16-bit weights]
  Result<cl_program> Program(bool joints16, bool weights16);
  // What a kernel writes: qskin_b*, qskin_normals_b*, qskin_tangents_b* (normals too).
  enum class Outputs { kPositions, kNormals, kTangents };
  Result<cl_kernel> Kernel(const OpenClLane& lane, const Mesh& mesh, Outputs outputs, bool local);

  cl_context context_;
  cl_device_id device_;
  std::string build_options_;
  int local_tiles_;
  std::mutex mutex_;
  cl_program programs_[2][2] = {};
  // (lane, 16-bit joints, 16-bit weights, B, outputs, local) -> kernel
  std::map<std::tuple<const OpenClLane*, bool, bool, uint32_t, Outputs, bool>, cl_kernel> kernels_;
};

}  // namespace skinserve
