// `sse`: the SSE loop on one thread.
#include "backend_factories.h"
#include "cpu_backend.h"
#include "cpu_model.h"
#include "sse_dual_quaternion_skinning.h"
#include "sse_skinning.h"

namespace skinserve {

std::unique_ptr<Backend> MakeSseBackend() {
  return std::make_unique<CpuBackend<sse::SseKernel, sse::SseDualQuaternionKernel>>(BackendInfo{
      .id = "sse",
      .description = "SSE2 on one thread: a matrix column per register, 4 vertices a step",
      .device = CpuModelName(),
      .simd_width = 4});
}

}  // namespace skinserve
