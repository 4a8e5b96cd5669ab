// Internal: the two OpenCL backends over one shared runtime.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "backends/common/dual_quaternion_palette.h"
#include "backends/opencl/opencl_quantized.h"
#include "backends/opencl/opencl_runtime.h"
#include "skinserve/engine/backend.h"

namespace skinserve {

// `threads`: host threads one frame occupies.
BackendInfo OpenClBackendInfo(const OpenClRuntime& runtime, const char* id, const char* description,
                              int threads);
class OpenClEncoder;
// Both backends of one runtime share its encoder (opencl_encode.h).
std::unique_ptr<Backend> MakeOpenClCopyBackend(std::shared_ptr<OpenClRuntime> runtime,
                                               std::shared_ptr<OpenClEncoder> encoder);
std::unique_ptr<Backend> MakeOpenClZeroCopyBackend(std::shared_ptr<OpenClRuntime> runtime,
                                                   std::shared_ptr<OpenClEncoder> encoder);
// {opencl, opencl-zerocopy} over one runtime created with `options` (MakeOpenClBackends of
// backend_factories.h with every option: the tests' coalesced and local-palette paths on
// PoCL, the benchmark's rows without the local palette); unavailable with the reason when
// the runtime cannot be created.
std::vector<std::unique_ptr<Backend>> MakeOpenClBackends(const OpenClRuntimeOptions& options);
// {opencl, opencl-zerocopy} over `runtime`; or both unavailable with `reason`.
std::vector<std::unique_ptr<Backend>> MakeOpenClBackendsOn(std::shared_ptr<OpenClRuntime> runtime);
std::vector<std::unique_ptr<Backend>> MakeUnavailableOpenClBackends(const std::string& reason);

// Both backends' Skin(): `frame` with its palette in the layout the kernels take - folded
// with a quantized mesh's box (after CheckQuantizedMethod), or
// as unit dual quaternions, converted once per frame - handed to `skin_palette`.
template <typename SkinPalette>
Status SkinWithKernelPalette(const std::string& backend_id, const PreparedMesh& base,
                             const SkinFrame& frame, const SkinPalette& skin_palette) {
  if (const QuantizedRest* rest = base.mesh().quantized_rest()) {
    if (Status s = CheckQuantizedMethod(backend_id, base.mesh(), frame.method); !s.ok()) return s;
    SkinFrame folded = frame;
    folded.palette = FoldedQuantizedPalette(frame.palette, *rest);
    return skin_palette(folded);
  }
  if (frame.method == SkinningMethod::kDualQuaternion) {
    const DualQuaternionPalette quaternions(frame.palette);
    SkinFrame converted = frame;
    converted.palette = quaternions.floats();
    return skin_palette(converted);
  }
  return skin_palette(frame);
}

// INVALID_ARGUMENT when `frame` asks for normals or tangents that `mesh` does not have
// (tangents come with normals).
Status CheckOpenClOutputs(const Mesh& mesh, const SkinFrame& frame);

}  // namespace skinserve
