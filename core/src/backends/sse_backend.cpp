// `sse`: the SSE loop on one thread.
#include "backend_factories.h"
#include "cpu_backend.h"
#include "cpu_model.h"
#if defined(__SSE2__)
#include "sse_dual_quaternion_skinning.h"
#include "sse_skinning.h"
#else
#include "unavailable_backend.h"
#endif

namespace skinserve {

std::unique_ptr<Backend> MakeSseBackend() {
#if defined(__SSE2__)
  return std::make_unique<CpuBackend<sse::SseKernel, sse::SseDualQuaternionKernel>>(BackendInfo{
      .id = "sse",
      .description = "SSE2 on one thread: a matrix column per register, 4 vertices a step",
      .device = CpuModelName(),
      .simd_width = 4});
#else
  // The paper's SSE2 loop is x86 only: listed, with the reason, elsewhere (Arm runs `simd`).
  return std::make_unique<UnavailableBackend>(BackendInfo{
      .id = "sse",
      .description = "SSE2 on one thread: a matrix column per register, 4 vertices a step",
      .unavailable_reason = kSseNeedsX86,
      .device = CpuModelName()});
#endif
}

}  // namespace skinserve
